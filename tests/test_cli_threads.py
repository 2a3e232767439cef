"""The command line runs the BLAS and OpenMP libraries one thread each unless the user set a
count in the environment (twoscale.cli.threads)."""

from __future__ import annotations

import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import twoscale.cli.solve as solve_command
from twoscale.cli.main import main
from twoscale.cli.threads import USER_THREAD_SETTINGS, command_threads


def _counts() -> list:
    return [pool["num_threads"] for pool in threadpool_info()]


@pytest.fixture
def two_threads(monkeypatch):
    """No count in the environment, and every pool allowed two threads meanwhile (as
    OpenBLAS's default gives on two cores), restored afterwards."""
    for name in USER_THREAD_SETTINGS:
        monkeypatch.delenv(name, raising=False)
    if not threadpool_info():
        pytest.skip("no BLAS or OpenMP library loaded")
    with threadpool_limits(limits=2):
        yield


def test_a_command_runs_single_threaded(two_threads, monkeypatch):
    seen, before = [], _counts()
    monkeypatch.setattr(solve_command, "run", lambda args: seen.append(_counts()) or 0)
    assert main(["solve", "scene.toml"]) == 0
    assert seen and all(n == 1 for n in seen[0])
    assert _counts() == before  # restored after the command


@pytest.mark.parametrize("name", USER_THREAD_SETTINGS)
def test_a_count_the_user_set_is_left_alone(two_threads, name):
    with command_threads({name: "2"}):
        assert max(_counts()) == 2
    with command_threads({}):
        assert max(_counts()) == 1
