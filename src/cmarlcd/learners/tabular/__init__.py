"""The tabular learners, one file each: CMARL-CD (:mod:`~.coordination`, Algorithms 1 and
2), the LA-OCA stand-in (:mod:`~.automata`) and the classic coordination learners
(:mod:`~.q_learning`, :mod:`~.distributed_q`, :mod:`~.fmq`, :mod:`~.hysteretic`,
:mod:`~.lenient`, :mod:`~.joint_action`, sharing :mod:`~.independent`), all speaking the
protocol of :mod:`~.protocol`: tables, compiled kernels and the object API.

Until 0.7 this package's name was the protocol's module; its names (``TabularConfig``,
``TabularLearner``, ...) still resolve here for one release, with a
:class:`DeprecationWarning` naming :mod:`cmarlcd.learners.tabular.protocol`.
"""

from __future__ import annotations

from cmarlcd._moved import moved_attribute


def __getattr__(name: str):
    return moved_attribute(__name__, "cmarlcd.learners.tabular.protocol", name, since="0.7")
