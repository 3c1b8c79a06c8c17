"""derive's commands run BLAS on one thread unless the user chose a number (derive.cli._one_blas_thread)."""
from __future__ import annotations

import os

import pytest

from derive import cli


@pytest.fixture
def no_thread_variables(monkeypatch):
    for name in cli.BLAS_THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)


def test_a_command_runs_blas_on_one_thread_and_says_so_to_its_worker_processes(no_thread_variables):
    import numpy  # noqa: F401 - numpy's OpenBLAS loaded, as by the time a command computes
    from threadpoolctl import threadpool_info

    with cli._one_blas_thread():
        assert all(os.environ[name] == "1" for name in cli.BLAS_THREAD_VARIABLES)
        blas = [pool for pool in threadpool_info() if pool["user_api"] == "blas"]
        assert blas and all(pool["num_threads"] == 1 for pool in blas)   # numpy's OpenBLAS, in this process


def test_a_users_own_thread_setting_is_kept(no_thread_variables, monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")
    with cli._one_blas_thread():
        assert os.environ["OPENBLAS_NUM_THREADS"] == "2"
        assert all(name not in os.environ for name in cli.BLAS_THREAD_VARIABLES if name != "OPENBLAS_NUM_THREADS")
