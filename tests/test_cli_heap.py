"""glibc's heap thresholds of a rolling run (``twoscale.cli.heap``)."""

import sys

import pytest

from twoscale.cli.heap import USER_HEAP_SETTINGS, keep_heap


@pytest.mark.parametrize("name", USER_HEAP_SETTINGS)
def test_a_users_heap_setting_is_kept(name):
    assert keep_heap({name: "131072"}) is False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_the_thresholds_are_set_on_glibc():
    import ctypes.util

    if "libc.so" not in (ctypes.util.find_library("c") or "libc.so"):
        pytest.skip("not glibc")
    assert keep_heap({}) is True
