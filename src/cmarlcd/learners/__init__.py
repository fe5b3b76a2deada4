"""Learners: CMARL-CD (coordination degree) and the paper's baselines."""

from cmarlcd.learners.coordination import CMARLCD, FitResult, RepeatedConfig

__all__ = ["CMARLCD", "FitResult", "RepeatedConfig"]
