"""The fault table: inject each fault into real ``twoscale`` processes, record what the
program did and what was kept, and write ``docs/faults.md``.

    python benchmarks/faults.py [--out docs/faults.md]

Faults (each on fresh temporary folders, only on this machine's loopback address):

* the surface-law cache of ``examples/road``: entries truncated, emptied, tampered (wrong
  checksum), written by another program (no checksum); the cache folder blocked by a file;
  a file-size limit (``RLIMIT_FSIZE``, what a full disk or quota does to a writer); two
  processes tabulating the same laws at once;
* the finite block's correction cache: its entry truncated;
* a study (24 cases): SIGTERM and SIGKILL of the driver mid-study, then the same command;
  a second run while the first is alive; a Dask scheduler and two workers started as
  separate processes, one worker killed with SIGKILL mid-study.

Every wait is bounded; every process started here is ended by its id.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout, like the child processes (PYTHONPATH below)
ROAD = ROOT / "examples" / "road"
ENV = dict(os.environ, PYTHONPATH=str(ROOT))
TIMEOUT = 300.0


def twoscale(*args: str, env: dict | None = None, timeout: float = TIMEOUT) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "twoscale", *args], env=env or ENV, capture_output=True, text=True, timeout=timeout
    )


def lines(text: str, prefix: str = "") -> list[str]:
    return [line for line in text.strip().splitlines() if line.startswith(prefix)]


def forces(folder: Path) -> list[float]:
    return [a["force"] for a in json.loads((folder / "result.json").read_text())["asperities"]]


# ------------------------------------------------------------------ the law cache
def road_scene(tmp: Path, extra: str = "") -> Path:
    text = (ROAD / "road.toml").read_text().replace('file = "road.npz"', f'file = "{ROAD / "road.npz"}"')
    text = text.replace('law = "auto"', 'law = "tabulated"').replace("[surface]\n", "[surface]\n" + extra)
    path = tmp / "road.toml"
    path.write_text(text)
    return path


def law_cache_rows(tmp: Path) -> list[tuple]:
    import numpy as np

    env = dict(ENV, TWOSCALE_CACHE_DIR=str(tmp / "cache"))
    scene = road_scene(tmp)
    assert twoscale("surface", str(ROAD / "road.toml"), "--out", str(tmp / "seg"), env=env).returncode == 0
    assert twoscale("solve", str(scene), "--out", str(tmp / "clean"), "--quiet", env=env).returncode == 0
    clean = forces(tmp / "clean")
    folder = tmp / "cache" / "surface-laws"
    used = json.loads((tmp / "clean" / "result.json").read_text())["caches"][0]["read"]

    def tamper(p: Path) -> None:
        with np.load(p) as d:
            arrays = {k: d[k] for k in d.files}
        arrays["P"] = arrays["P"] * 1.01
        np.savez(p, **arrays)

    def foreign(p: Path) -> None:
        with np.load(p) as d:
            arrays = {k: d[k] for k in d.files if k != "_sha256"}
        np.savez(p, **arrays)

    damages = [
        ("1 law entry truncated to half, 4 emptied (the reported crash: EOFError/BadZipFile traceback before)", None),
        ("1 law entry's table changed after its checksum (tampered, or mixed by a bad copy)", tamper),
        ("1 law entry rewritten without a checksum (another program or version)", foreign),
    ]
    rows = []
    for k, (what, damage) in enumerate(damages):
        victims = sorted(folder.glob("*.npz"))[: 5 if damage is None else 1]
        if damage is None:
            data = victims[0].read_bytes()
            victims[0].write_bytes(data[: len(data) // 2])
            for p in victims[1:]:
                p.write_bytes(b"")
        else:
            damage(victims[0])
        out = tmp / f"damaged{k}"
        r = twoscale("solve", str(scene), "--out", str(out), "--quiet", env=env)
        usage = json.loads((out / "result.json").read_text())["caches"][0] if r.returncode == 0 else {}
        same = r.returncode == 0 and np.allclose(forces(out), clean, rtol=1e-10, atol=1e-12)
        rows.append(
            (
                what,
                f"exit {r.returncode}; {len(lines(r.stderr, 'warning: cache entry'))} warning line(s) "
                f"naming the entries; {'no' if 'Traceback' not in r.stderr else 'a'} traceback",
                f"dropped {len(usage.get('dropped', []))} (result.json caches), rebuilt; the other "
                f"{usage.get('read', 0)} of {used} laws read; forces {'equal' if same else 'DIFFERENT'} "
                f"to the clean cache's",
            )
        )
    blocked = tmp / "blocked"
    blocked.write_text("")
    (tmp / "b").mkdir()
    scene2 = road_scene(tmp / "b", f'law_cache = "{blocked}"\n')
    r = twoscale("solve", str(scene2), "--out", str(tmp / "blocked-out"), "--quiet", env=env)
    rows.append(
        (
            "law cache folder path taken by a file (an unwritable folder)",
            f"exit {r.returncode}; {len(lines(r.stderr, 'warning: cache folder'))} warning line",
            "solved without storing laws; forces "
            + ("equal" if r.returncode == 0 and np.allclose(forces(tmp / "blocked-out"), clean) else "DIFFERENT"),
        )
    )
    rows.append(full_disk_row(tmp))
    rows.append(concurrent_row(tmp))
    return rows


FULL = """
import resource, signal, sys, warnings
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))   # every law entry is larger
from twoscale import Material
from twoscale.surface import LawCache, RawMap, SurfaceOptions, build_surface
from twoscale.surface.texture import road
with warnings.catch_warnings(record=True) as rec:
    warnings.simplefilter("always")
    s = build_surface(RawMap(road(12.0, 0.1, seed=4), 0.1, "mm", None, "road"), SurfaceOptions(law="tabulated"),
                      cache=LawCache(sys.argv[1]))
    s.book.table(Material(10.0, 0.5))
u = s.book.cache.usage()
print(len(rec), s.book.tabulated, u.written, repr(u.disabled))
"""


def full_disk_row(tmp: Path) -> tuple:
    r = subprocess.run(
        [sys.executable, "-c", FULL, str(tmp / "full")], env=ENV, capture_output=True, text=True, timeout=TIMEOUT
    )
    n_warn, tabulated, written, why = r.stdout.split(maxsplit=3) if r.returncode == 0 else ("?", "?", "?", "?")
    left = sorted(p.name for p in (tmp / "full").glob("*")) if (tmp / "full").exists() else []
    return (
        "file-size limit of 1 kB on the law writer (RLIMIT_FSIZE: what a full disk or quota does)",
        f"exit {r.returncode}; {n_warn} warning ({why.strip()})",
        f"all {tabulated} laws tabulated and used in memory, {written} written, {len(left)} files left",
    )


CONCURRENT = """
import sys, time
import numpy as np
from twoscale import Material
from twoscale.surface import LawCache, RawMap, SurfaceOptions, build_surface
from twoscale.surface.texture import road
s = build_surface(RawMap(road(12.0, 0.1, seed=4), 0.1, "mm", None, "road"), SurfaceOptions(law="tabulated"),
                  cache=LawCache(sys.argv[1]))
while time.time() < float(sys.argv[2]):
    time.sleep(0.001)
s.book.table(Material(10.0, 0.5))
print(s.book.tabulated)
"""


def concurrent_row(tmp: Path) -> tuple:
    from twoscale.io.cache_entry import BadEntry, read_entry

    start = str(time.time() + 2.0)
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", CONCURRENT, str(tmp / "both"), start],
            env=ENV,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(2)
    ]
    outs = [p.communicate(timeout=TIMEOUT) for p in procs]
    bad = 0
    entries = sorted((tmp / "both").iterdir())
    for p in entries:
        try:
            read_entry(p)
        except BadEntry:
            bad += 1
    return (
        "two processes tabulating the same laws into one cache folder at the same moment",
        f"exits {[p.returncode for p in procs]}; each tabulated {[o[0].strip() for o in outs]}",
        f"{len(entries)} entries, {bad} damaged, no temporary files "
        f"({'none' if all(p.suffix == '.npz' for p in entries) else 'SOME'} left)",
    )


def block_row(tmp: Path) -> tuple:
    import warnings

    import numpy as np

    from fem_influence import BlockProvider
    from twoscale.material import Material

    small = dict(
        material=Material(2.0, 0.5),
        size=(60.0, 60.0, 10.0),
        h_fine=5.0,
        h_coarse=10.0,
        fine_half_width=10.0,
        progress=False,
        cache_dir=tmp / "fem",
    )
    t, s = np.array([[5.0, 0.0], [0.0, 9.0]]), np.array([[0.0, 0.0], [1.0, 2.0]])
    C1 = BlockProvider(**small).correction(t, s)
    [entry] = (tmp / "fem").glob("block-*.npz")
    data = entry.read_bytes()
    entry.write_bytes(data[: len(data) // 3])
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        again = BlockProvider(**small)
        C2 = again.correction(t, s)
    u = again.cache_usage()[0]
    from twoscale.io.cache_entry import CacheWarning

    said = [w for w in rec if issubclass(w.category, CacheWarning)]
    return (
        "the block's correction cache entry truncated to a third",
        f"{len(said)} warning line naming it ({len(rec) - len(said)} other warnings); the fields solved again",
        f"dropped {len(u.dropped)}, written {u.written}; correction "
        f"{'equal' if np.allclose(C1, C2, rtol=1e-10) else 'DIFFERENT'} to the first build's",
    )


# ------------------------------------------------------------------ studies
STUDY = """
[study]
name = "faults"
[[scene]]
file = "scene.toml"
name = "pair"
[[body]]
name = "hs"
kind = "halfspace"
[load]
penetration = [0.05]
[positions]
start = [0.0, 0.0]
end = [5.75, 0.0]
step = 0.25
[solver]
h = 0.025
"""
SCENE = "[material]\nE = 10.0\nnu = 0.5\n[load]\npenetration = 0.1\n[grid]\nh = 0.1\n" + "".join(
    f'[[asperity]]\nx = {x}\ny = 0.0\nz = 0.0\nR = 10.0\nshape = "paraboloid"\n' for x in (-3.0, 3.0)
)


def study_dir(tmp: Path, name: str) -> Path:
    folder = tmp / name
    folder.mkdir()
    (folder / "scene.toml").write_text(SCENE)
    (folder / "study.toml").write_text(STUDY)
    return folder


def start_study(folder: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "twoscale",
            "study",
            str(folder / "study.toml"),
            "--out",
            str(folder / "out"),
            "--quiet",
            *extra,
        ],
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def n_cases(out: Path) -> int:
    folder = out / "cases"
    return sum(1 for p in folder.iterdir() if not p.name.startswith(".")) if folder.is_dir() else 0


def wait_cases(proc: subprocess.Popen, out: Path, n: int, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while n_cases(out) < n and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)


def end(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=30)


def whole_cases(out: Path) -> int:
    """Case folders whose case.json and sensor.npy read back (no temporary folder counted)."""
    import numpy as np

    n = 0
    for case in (out / "cases").iterdir():
        if case.name.startswith("."):
            continue
        try:
            json.loads((case / "case.json").read_text())
            np.load(case / "sensor.npy")
            n += 1
        except (OSError, ValueError):
            pass
    return n


def tables(out: Path):
    import pandas as pd

    a = pd.read_csv(out / "cases.csv").drop(columns=["seconds", "strategy"])
    return a


def study_rows(tmp: Path) -> list[tuple]:
    ref = study_dir(tmp, "ref")
    assert (
        twoscale("study", str(ref / "study.toml"), "--out", str(ref / "out"), "--workers", "0", "--quiet").returncode
        == 0
    )
    ref_table = tables(ref / "out")
    rows = []
    for sig in (signal.SIGTERM, signal.SIGKILL):
        f = study_dir(tmp, sig.name)
        p = start_study(f, "--workers", "0")
        try:
            wait_cases(p, f / "out", 3)
            os.kill(p.pid, sig)
            _, err = p.communicate(timeout=60)
        finally:
            end(p)
        kept, whole = n_cases(f / "out"), whole_cases(f / "out")
        r = twoscale("study", str(f / "study.toml"), "--out", str(f / "out"), "--workers", "0")
        got = tables(f / "out")
        same, unique = got.equals(ref_table), got["key"].is_unique
        said = "; ".join(lines(err)) or "nothing"
        rows.append(
            (
                f"{sig.name} to the study driver after 3 of 24 cases, then the same command",
                f"exit {p.returncode} ({'signal' if p.returncode < 0 else 'code'}), said: {said}; "
                f"the rerun: exit {r.returncode}, {lines(r.stdout)[0].split(';')[1].strip()}",
                f"{kept} finished cases kept, {whole} of them whole; tables {'equal' if same else 'DIFFERENT'} "
                f"to an uninterrupted run's ({len(got)} rows, keys {'unique' if unique else 'REPEATED'})",
            )
        )
    f = study_dir(tmp, "busy")
    p = start_study(f, "--workers", "0")
    try:
        wait_cases(p, f / "out", 1)
        r = twoscale("study", str(f / "study.toml"), "--out", str(f / "out"), "--workers", "0")
        named = f"pid {p.pid}" in r.stderr
        before = n_cases(f / "out")
        os.kill(p.pid, signal.SIGKILL)
        p.communicate(timeout=60)
    finally:
        end(p)
    r2 = twoscale("study", str(f / "study.toml"), "--out", str(f / "out"), "--workers", "0", "--quiet")
    rows.append(
        (
            "a second run on the same folder while the first is alive; then the first killed (SIGKILL) "
            "and the command run again",
            f"second: exit {r.returncode}, {len(lines(r.stderr))} line, naming the holder's pid: "
            f"{'yes' if named else 'NO'}; after the kill: exit {r2.returncode} (no wait, nothing removed by hand)",
            f"the first run's {before} cases kept; {n_cases(f / 'out')} after the rerun; tables "
            f"{'equal' if tables(f / 'out').equals(ref_table) else 'DIFFERENT'} to an uninterrupted run's",
        )
    )
    rows.append(local_cluster_row(tmp, ref_table))
    rows.append(dask_row(tmp, ref_table))
    return rows


def group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def local_cluster_row(tmp: Path, ref_table) -> tuple:
    f = study_dir(tmp, "local")
    p = start_study(f, "--workers", "2")
    try:
        wait_cases(p, f / "out", 3)
        os.kill(p.pid, signal.SIGKILL)
        p.communicate(timeout=60)
        t0 = time.monotonic()
        while group_alive(p.pid) and time.monotonic() - t0 < 60:
            time.sleep(0.1)
        gone = time.monotonic() - t0
        orphans = group_alive(p.pid)
    finally:
        if group_alive(p.pid):
            os.killpg(p.pid, signal.SIGKILL)
    kept = n_cases(f / "out")
    r = twoscale("study", str(f / "study.toml"), "--out", str(f / "out"), "--workers", "2", "--quiet")
    same = r.returncode == 0 and tables(f / "out").equals(ref_table)
    return (
        "SIGKILL to the driver of a local Dask cluster (--workers 2) after 3 of 24 cases, then the same command",
        f"its worker processes {'still alive after 60 s' if orphans else f'ended by themselves within {gone:.1f} s'} "
        f"(their nannies watch the driver); the rerun: exit {r.returncode}",
        f"{kept} finished cases kept; tables {'equal' if same else 'DIFFERENT'} to an uninterrupted run's",
    )


def dask_row(tmp: Path, ref_table) -> tuple:
    f = study_dir(tmp, "dask")
    sched_file = f / "scheduler.json"
    procs = []

    def spawn(*args):
        p = subprocess.Popen(
            [sys.executable, "-m", *args],
            env=ENV,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            cwd=f,
        )
        procs.append(p)
        return p

    try:
        spawn(
            "distributed.cli.dask_scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            "0",
            "--no-dashboard",
            "--scheduler-file",
            str(sched_file),
        )
        deadline = time.monotonic() + 60
        while (not sched_file.exists() or not sched_file.read_text().strip()) and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        workers = [
            spawn(
                "distributed.cli.dask_worker",
                "--scheduler-file",
                str(sched_file),
                "--host",
                "127.0.0.1",
                "--nthreads",
                "1",
                "--no-nanny",
                "--no-dashboard",
                "--death-timeout",
                "60",
            )
            for _ in range(2)
        ]
        driver = start_study(f, "--scheduler", address)
        procs.append(driver)
        wait_cases(driver, f / "out", 4)
        os.kill(workers[0].pid, signal.SIGKILL)
        driver.communicate(timeout=TIMEOUT)
        codes = [driver.returncode]
        if driver.returncode == 1:
            again = start_study(f, "--scheduler", address)
            procs.append(again)
            again.communicate(timeout=TIMEOUT)
            codes.append(again.returncode)
    finally:
        for p in procs:
            end(p)
    same = tables(f / "out").equals(ref_table)
    return (
        "`dask scheduler` + two `dask worker` processes on 127.0.0.1 (--scheduler); one worker "
        "SIGKILLed after 4 of 24 cases",
        f"exit codes {codes} ({'every case converged in the one run, none failed with the worker' if codes == [0] else 'cases lost with the worker recorded as failed, solved by the rerun'})",
        f"{n_cases(f / 'out')} cases; tables {'equal' if same else 'DIFFERENT'} to the serial run's",
    )


# ------------------------------------------------------------------ the table
def write(rows: list[tuple], path: Path, seconds: float) -> None:
    head = path.read_text().split("<!-- table -->")[0] if path.exists() else ""
    table = ["<!-- table -->", "", "| fault injected | what the program did | what was kept |", "|---|---|---|"]
    table += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    table += [
        "",
        f"Written by `python benchmarks/faults.py` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} "
        f"({seconds:.0f} s).",
        "",
    ]
    path.write_text(head + "\n".join(table))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "faults.md"))
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, make in (("laws", law_cache_rows), ("block", lambda t: [block_row(t)]), ("study", study_rows)):
            (tmp / name).mkdir()
            got = make(tmp / name)
            for row in got:
                print(" | ".join(row), flush=True)
            rows.extend(got)
    write(rows, Path(args.out), time.perf_counter() - t0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
