"""The on-disk caches under faults: damaged entries, unwritable folders, concurrent writers.

Every cache entry goes through :mod:`twoscale.io.cache_entry` (atomic write, checksum
checked on read). Injected here: a truncated, an emptied, a tampered (wrong checksum),
a foreign (no checksum) and a misnamed entry; a cache folder that cannot be created or
written (a file in its place, a full disk); two processes building the same entries at
once. What must hold: the solve goes on with the same answer, each damaged entry is
named in one warning line and rebuilt, result.json says what came from the cache.
"""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from twoscale.cli.main import main
from twoscale.io.cache_entry import (
    BadEntry,
    CacheWarning,
    EntryFolder,
    read_entry,
    write_entry,
)

ROOT = Path(__file__).resolve().parents[1]
ROAD = ROOT / "examples" / "road"


def _truncate(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _cache_warnings(record) -> list[str]:
    return [str(w.message) for w in record if issubclass(w.category, CacheWarning)]


# ------------------------------------------------------------------ the entry format
def test_entry_round_trip_and_every_kind_of_damage(tmp_path):
    arrays = {"a": np.arange(6.0).reshape(2, 3), "key": np.array("abc"), "flag": np.array(True)}
    path = tmp_path / "e.npz"
    size = write_entry(path, arrays)
    assert size == path.stat().st_size
    back = read_entry(path)
    assert set(back) == set(arrays) and np.array_equal(back["a"], arrays["a"]) and str(back["key"]) == "abc"
    assert [p.name for p in tmp_path.iterdir()] == ["e.npz"]  # no temporary file left
    with pytest.raises(FileNotFoundError):
        read_entry(tmp_path / "absent.npz")
    cases = {}
    cases["truncated"] = lambda p: _truncate(p)
    cases["emptied"] = lambda p: p.write_bytes(b"")
    cases["garbage"] = lambda p: p.write_bytes(b"\x00" * 100)
    # a whole npz whose arrays were changed after the checksum (a tampered or mixed entry)
    cases["checksum"] = lambda p: np.savez(
        p, a=np.zeros((2, 3)), key=np.array("abc"), flag=np.array(True), _sha256=read_entry_checksum(p)
    )
    cases["no checksum"] = lambda p: np.savez(p, **arrays)
    cases["text"] = lambda p: p.write_bytes(b"junk\n")
    for damage in cases.values():
        write_entry(path, arrays)
        damage(path)
        with pytest.raises(BadEntry):
            read_entry(path)
    # a file that is no zip at all is named so, not as "pickled data" (numpy's guess)
    for junk in (b"junk\n", b"\x00" * 100):
        path.write_bytes(junk)
        with pytest.raises(BadEntry, match="not an npz") as exc:
            read_entry(path)
        assert "pickle" not in str(exc.value)


def read_entry_checksum(path: Path) -> np.ndarray:
    with np.load(path) as d:
        return d["_sha256"]


def test_entry_folder_drops_a_bad_entry_with_one_warning_and_counts_it(tmp_path):
    folder = EntryFolder("test", tmp_path)
    assert folder.save("x.npz", {"v": np.ones(3)}) is not None
    _truncate(tmp_path / "x.npz")
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        assert folder.load("x.npz") is None
        assert folder.load("x.npz") is None  # gone now: absent, no second warning
    lines = _cache_warnings(rec)
    assert len(lines) == 1 and "x.npz" in lines[0] and "\n" not in lines[0]
    assert not (tmp_path / "x.npz").exists()
    assert folder.save("x.npz", {"v": np.ones(3)}) is not None
    assert np.array_equal(folder.load("x.npz")["v"], np.ones(3))
    u = folder.usage()
    assert (u.read, u.written, u.dropped, u.disabled) == (1, 1, ("x.npz",), "")  # x: one file, stored twice


def test_many_bad_entries_give_a_bounded_number_of_lines(tmp_path):
    folder = EntryFolder("test", tmp_path)
    for k in range(12):
        (tmp_path / f"{k}.npz").write_bytes(b"")
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        for k in range(12):
            assert folder.load(f"{k}.npz") is None
    assert len(_cache_warnings(rec)) == 6  # five named, then one line for the rest
    assert len(folder.usage().dropped) == 12


@pytest.mark.parametrize(
    "fault",
    [
        "file in place of the folder",
        "disk full",
        pytest.param(
            "read-only folder", marks=pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
        ),
    ],
)
def test_an_unwritable_folder_warns_once_and_keeps_nothing(tmp_path, monkeypatch, fault):
    if fault == "file in place of the folder":
        where = tmp_path / "blocked"
        where.write_text("not a folder")
    elif fault == "read-only folder":
        where = tmp_path / "ro"
        where.mkdir()
        where.chmod(0o500)
    else:
        where = tmp_path / "full"

        def full(*args, **kwargs):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        monkeypatch.setattr(np, "savez", full)
    folder = EntryFolder("test", where)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        assert folder.save("a.npz", {"v": np.ones(2)}) is None
        assert folder.save("b.npz", {"v": np.ones(2)}) is None
    lines = _cache_warnings(rec)
    assert len(lines) == 1 and "cannot be written" in lines[0]
    assert folder.usage().disabled and folder.usage().written == 0
    leftovers = [p for p in tmp_path.rglob("*") if p.name.endswith(".tmp")]
    assert leftovers == []


# ------------------------------------------------------------------ the reported crash
def _road_scene(tmp_path: Path, law: str = "tabulated") -> Path:
    text = (ROAD / "road.toml").read_text(encoding="utf-8")
    text = text.replace('file = "road.npz"', f'file = "{(ROAD / "road.npz").as_posix()}"')
    text = text.replace('law = "auto"', f'law = "{law}"')
    path = tmp_path / "road.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_damaged_law_cache_of_the_example_road_warns_and_solves_the_same(tmp_path, monkeypatch, capsys):
    """The reported case: the road's laws cached by ``twoscale surface``, one law file
    truncated and four emptied, then ``twoscale solve`` with ``law = "tabulated"``: it
    used to end in a traceback (EOFError / BadZipFile)."""
    from twoscale.io.scene_file import read_scene
    from twoscale.api import solve_scene

    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path / "cache"))
    scene = _road_scene(tmp_path)
    assert main(["surface", str(ROAD / "road.toml"), "--out", str(tmp_path / "seg")]) == 0
    laws = sorted((tmp_path / "cache" / "surface-laws").glob("*.npz"))
    assert len(laws) == 100
    clean = solve_scene(read_scene(scene), provider_options=None)
    assert clean.caches[0].read > 50 and clean.caches[0].written == 0
    # damage five laws the solve reads (the stones it presses): one truncated, four emptied
    victims = laws[:5]
    _truncate(victims[0])
    for p in victims[1:]:
        p.write_bytes(b"")
    capsys.readouterr()
    assert main(["solve", str(scene), "--out", str(tmp_path / "damaged"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err
    dropped = [line for line in err.splitlines() if line.startswith("warning: cache entry")]
    damaged = json.loads((tmp_path / "damaged" / "result.json").read_text())
    [usage] = damaged["caches"]
    assert usage["name"] == "surface-laws" and usage["written"] == len(usage["dropped"]) > 0
    assert set(usage["dropped"]) <= {p.name for p in victims} and len(dropped) == len(usage["dropped"])
    assert all(any(name in line for line in dropped) for name in usage["dropped"])
    # the rebuilt tables are the same tables: the same answer
    np.testing.assert_allclose(
        [a["force"] for a in damaged["asperities"]], clean.asperities.forces, rtol=1e-10, atol=1e-12
    )
    # and the cache is whole again: the next solve reads every law it needs
    again = solve_scene(read_scene(scene)).caches[0]
    assert again.dropped == () and again.written == 0 and again.read == clean.caches[0].read


def test_law_cache_that_cannot_be_written_solves_without_it(tmp_path, capsys):
    from twoscale.surface.texture import road

    # a 12 mm road of the same texture (a few stones: the fault, not the solve, is tested)
    np.savez(tmp_path / "small.npz", heights=road(12.0, 0.1, seed=4), spacing=np.array(0.1), units=np.array("mm"))
    blocked = tmp_path / "cache-is-a-file"
    blocked.write_text("")
    scene = tmp_path / "small.toml"
    scene.write_text(
        '[material]\nE = 10.0\nnu = 0.5\n[load]\ntotal = 20.0\n[surface]\nfile = "small.npz"\n'
        f'law = "tabulated"\nlaw_cache = "{blocked.name}"\n'
    )
    capsys.readouterr()
    assert main(["solve", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "cannot be written" in line]
    assert len(lines) == 1 and "Traceback" not in err
    [usage] = json.loads((tmp_path / "out" / "result.json").read_text())["caches"]
    assert usage["disabled"] and usage["written"] == 0 and usage["read"] == 0


# ------------------------------------------------------------------ the block's cache
def test_damaged_block_cache_is_dropped_and_solved_again(tmp_path):
    from fem_influence import BlockProvider
    from twoscale.material import Material

    small = dict(
        material=Material(2.0, 0.5),
        size=(60.0, 60.0, 10.0),
        h_fine=5.0,
        h_coarse=10.0,
        fine_half_width=10.0,
        progress=False,
        cache_dir=tmp_path,
    )
    t, s = np.array([[5.0, 0.0], [0.0, 9.0]]), np.array([[0.0, 0.0], [1.0, 2.0]])
    C1 = BlockProvider(**small).correction(t, s)
    [entry] = tmp_path.glob("block-*.npz")
    _truncate(entry)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        again = BlockProvider(**small)
        C2 = again.correction(t, s)
    [line] = _cache_warnings(rec)
    assert entry.name in line
    assert again._state.solver is not None  # solved again, not read
    np.testing.assert_allclose(C2, C1, rtol=1e-10, atol=1e-14)
    [usage] = again.cache_usage()
    assert usage.dropped == (entry.name,) and usage.written >= 1
    warm = BlockProvider(**small)
    warm.correction(t, s)
    assert warm._state.solver is None and warm.cache_usage()[0].read == 1


def test_an_entry_stored_again_is_written_once(tmp_path):
    folder = EntryFolder("c", tmp_path)
    folder.save("a.npz", {"x": np.zeros(2)})
    snapshot = folder.usage()
    for name in ("a.npz", "b.npz", "a.npz"):  # a grows twice more, b is new
        folder.save(name, {"x": np.zeros(3)})
    assert folder.usage().written == len(list(tmp_path.glob("*.npz"))) == 2
    assert folder.usage().as_dict()["written"] == 2
    assert folder.usage().since(snapshot).written == 2  # a stored again after the snapshot counts
    assert folder.usage().since(folder.usage()).written == 0


_BLOCK_SCENE = """
[material]
E = 5.0
nu = 0.5

[influence]
kind = "block"
size = [40.0, 40.0, 5.0]

[load]
total = 10.0

[[asperity]]
x = 0.0
y = 0.0
R = 4.0
"""


def test_solve_records_the_damaged_block_entry_it_dropped(tmp_path, monkeypatch, capsys):
    # the command checks the memory on the body it then solves on: built twice, the second
    # build would find the entry gone and result.json would say nothing was dropped
    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path / "cache"))
    scene = tmp_path / "block.toml"
    scene.write_text(_BLOCK_SCENE)
    assert main(["solve", str(scene), "--out", str(tmp_path / "cold"), "--quiet"]) == 0
    [entry] = (tmp_path / "cache").glob("block-*.npz")
    _truncate(entry)
    assert main(["solve", str(scene), "--out", str(tmp_path / "again"), "--quiet"]) == 0
    assert sum(entry.name in line for line in capsys.readouterr().err.splitlines()) == 1
    cold, again = (json.loads((tmp_path / d / "result.json").read_text()) for d in ("cold", "again"))
    # the block's one entry is stored again as each batch of fields is added: one file written
    assert cold["caches"][0]["written"] == 1
    [usage] = again["caches"]
    assert usage["dropped"] == [entry.name] and usage["read"] == 0 and usage["written"] >= 1
    assert again["penetration"] == pytest.approx(cold["penetration"], rel=1e-9)
    assert main(["solve", str(scene), "--out", str(tmp_path / "warm"), "--quiet"]) == 0
    [usage] = json.loads((tmp_path / "warm" / "result.json").read_text())["caches"]
    assert usage["read"] == 1 and usage["dropped"] == []


def test_compare_records_the_damaged_block_entry_it_dropped(tmp_path, monkeypatch, capsys):
    # as above: the memory check runs on the block the solves use, not on one built for it
    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path / "cache"))
    scene = tmp_path / "block.toml"
    scene.write_text(_BLOCK_SCENE)
    assert main(["solve", str(scene), "--quiet"]) == 0
    [entry] = (tmp_path / "cache").glob("block-*.npz")
    _truncate(entry)
    out = tmp_path / "cmp"
    assert main(["compare", str(scene), "--base", "bonded", "--out", str(out), "--quiet"]) == 0
    assert sum(entry.name in line for line in capsys.readouterr().err.splitlines()) == 1
    [usage] = json.loads((out / "runs" / "block-bonded_10N" / "result.json").read_text())["caches"]
    assert usage["dropped"] == [entry.name] and usage["read"] == 0


# ------------------------------------------------------------------ two processes at once
_WRITER = textwrap.dedent("""
    import sys, time
    import numpy as np
    from twoscale.io.cache_entry import write_entry, read_entry
    path, start, seed = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
    while time.time() < start:
        time.sleep(0.001)
    data = {"v": np.arange(200_000, dtype=float), "key": np.array("same")}   # 1.6 MB: slow to write
    for _ in range(40):
        write_entry(path, data)
        read_entry(path)          # raises (exit 1) on a partial or mixed entry
""")


def test_two_processes_writing_one_entry_both_succeed_and_leave_it_whole(tmp_path):
    path = tmp_path / "entry.npz"
    start = time.time() + 1.5
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", _WRITER, str(path), str(start), str(k)], env=env, stderr=subprocess.PIPE, text=True
        )
        for k in range(2)
    ]
    reads = 0
    deadline = time.time() + 60
    while any(p.poll() is None for p in procs) and time.time() < deadline:
        if path.exists():
            assert np.array_equal(read_entry(path)["v"], np.arange(200_000, dtype=float))
            reads += 1
        time.sleep(0.005)
    outs = [p.communicate(timeout=60)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], outs
    assert str(read_entry(path)["key"]) == "same"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["entry.npz"]  # no temporary files left
    assert reads > 0


_SURFACE_RUN = textwrap.dedent("""
    import sys, time, warnings
    import numpy as np
    from twoscale import Material
    from twoscale.surface import LawCache, RawMap, SurfaceOptions, build_surface
    from twoscale.surface.texture import road
    folder, start = sys.argv[1], float(sys.argv[2])
    warnings.simplefilter("error")   # a damaged entry met on the way fails the process
    s = build_surface(RawMap(road(12.0, 0.1, seed=4), 0.1, "mm", None, "road"),
                      SurfaceOptions(law="tabulated"), cache=LawCache(folder))
    while time.time() < start:
        time.sleep(0.001)
    t = s.book.table(Material(10.0, 0.5))
    np.save(sys.argv[3], t.P)
    print(s.book.tabulated, len(s.asperities))
""")


def test_two_processes_tabulating_the_same_laws_both_succeed(tmp_path):
    from twoscale import Material
    from twoscale.surface import LawCache, RawMap, SurfaceOptions, build_surface
    from twoscale.surface.texture import road

    folder = tmp_path / "laws"
    start = time.time() + 2.0
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", _SURFACE_RUN, str(folder), str(start), str(tmp_path / f"P{k}.npy")],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for k in range(2)
    ]
    outs = [p.communicate(timeout=120) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [o[1] for o in outs]
    P0, P1 = np.load(tmp_path / "P0.npy"), np.load(tmp_path / "P1.npy")
    np.testing.assert_array_equal(P0, P1)
    # one valid entry per asperity, nothing else left
    n = int(outs[0][0].split()[1])
    entries = sorted(folder.iterdir())
    assert len(entries) == n and all(p.suffix == ".npz" for p in entries)
    for p in entries:
        read_entry(p)
    # and a third run reads them all
    s = build_surface(
        RawMap(road(12.0, 0.1, seed=4), 0.1, "mm", None, "road"),
        SurfaceOptions(law="tabulated"),
        cache=LawCache(folder),
    )
    np.testing.assert_array_equal(s.book.table(Material(10.0, 0.5)).P, P0)
    assert s.book.tabulated == 0 and s.book.cache.usage().read == n


def test_law_cache_finds_an_entry_by_its_name_and_counts_its_bytes_once_listed(tmp_path):
    """A fresh cache looks an entry up by its file (the folder is listed only when a law is
    put): it finds a table another run wrote, misses an absent one, and its running total of
    bytes after a put holds every entry, the one read before the listing too."""
    import numpy as np

    from twoscale.surface.lawcache import LawCache
    from twoscale.surface.laws import LawTable

    def table(scale: float) -> LawTable:
        delta = np.linspace(0.0, 0.01, 5)[None]
        return LawTable(delta, scale * delta**1.5, 10.0, 0.1, True)

    LawCache(tmp_path).put("a" * 64, table(1.0))
    fresh = LawCache(tmp_path)
    found = fresh.get("a" * 64)
    assert found is not None and np.array_equal(found.P, table(1.0).P)
    assert fresh.get("b" * 64) is None
    assert (fresh.hits, fresh.misses) == (1, 1)
    fresh.put("c" * 64, table(2.0))
    sizes = sum(p.stat().st_size for p in tmp_path.glob("*.npz"))
    assert len(list(tmp_path.glob("*.npz"))) == 2 and fresh.nbytes == sizes
