"""The command line and the Python entry points run the BLAS and OpenMP libraries one thread
each unless the user set a count in the environment, and give the counts back
(twoscale.threads)."""

from __future__ import annotations

import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import twoscale
import twoscale.api as api
import twoscale.cli.solve as solve_command
import twoscale.solver as solver_module
from twoscale.cli.main import main
from twoscale.threads import USER_THREAD_SETTINGS, single_threads

TIPS = [[0.0, 0.0, 5.0], [2.5, 0.0, 5.0]]


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


@pytest.fixture
def seen_in_solve(monkeypatch):
    """The thread counts in force while a solve runs its method (recorded there)."""
    seen: list = []
    run = api._run_method

    def recording(*args, **kwargs):
        seen.append(_counts())
        return run(*args, **kwargs)

    monkeypatch.setattr(api, "_run_method", recording)
    return seen


def test_a_command_runs_single_threaded(two_threads, monkeypatch):
    seen, before = [], _counts()
    monkeypatch.setattr(solve_command, "run", lambda args: seen.append(_counts()) or 0)
    assert main(["solve", "scene.toml"]) == 0
    assert seen and all(n == 1 for n in seen[0])
    assert _counts() == before  # restored after the command


@pytest.mark.parametrize("name", USER_THREAD_SETTINGS)
def test_a_count_the_user_set_is_left_alone(two_threads, name):
    with single_threads({name: "2"}):
        assert max(_counts()) == 2
    with single_threads({}):
        assert max(_counts()) == 1


def test_a_python_solve_runs_single_threaded_and_gives_the_counts_back(two_threads, seen_in_solve):
    before = _counts()
    result = twoscale.solve(TIPS, material=twoscale.Material(10.0, 0.5), total_load=1.0)
    assert result.converged
    assert seen_in_solve and max(seen_in_solve[0]) == 1
    assert _counts() == before


def test_a_python_solve_keeps_the_counts_the_user_set(two_threads, seen_in_solve, monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")
    twoscale.solve(TIPS, material=twoscale.Material(10.0, 0.5), total_load=1.0)
    assert seen_in_solve and max(seen_in_solve[0]) == 2


def test_a_solver_object_limits_its_solves_and_looks_the_libraries_up_once(two_threads, seen_in_solve, monkeypatch):
    made = []
    make = solver_module.thread_controller
    monkeypatch.setattr(solver_module, "thread_controller", lambda: made.append(1) or make())
    solver, before = twoscale.ContactSolver(), _counts()
    for load in (1.0, 1.2):
        solver.solve(TIPS, material=twoscale.Material(10.0, 0.5), total_load=load)
    assert len(seen_in_solve) == 2 and all(max(counts) == 1 for counts in seen_in_solve)
    assert len(made) == 1
    assert _counts() == before


def test_a_python_rolling_run_runs_single_threaded(two_threads, monkeypatch):
    import twoscale.rolling.run as rolling_run

    seen, before = [], _counts()
    monkeypatch.setattr(rolling_run, "_roll", lambda *args: seen.append(_counts()))
    twoscale.rolling.roll(object())
    assert seen and max(seen[0]) == 1
    assert _counts() == before
