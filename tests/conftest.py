"""Fixtures any test may take: ``paths``, where a command's end-to-end run stores its
runs and draws its figures (neither exists yet), and the options that say so."""

from __future__ import annotations

import pytest


@pytest.fixture
def paths(tmp_path):
    store, figures = tmp_path / "store.sqlite", tmp_path / "figures"
    return store, figures, ["--store", str(store), "--figures", str(figures)]
