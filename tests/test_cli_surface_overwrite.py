"""``twoscale surface --out DIR`` on a folder of its own earlier run: replaced with
``--overwrite``, as for ``solve``, ``compare`` and ``paper``.

The refusal of a non-empty folder told the user to "add --overwrite", an option
``twoscale surface`` did not accept ("unrecognized arguments"), so a second segmentation
could never go where the first one went. A folder holding files twoscale did not write is
still refused, with or without it.
"""

from __future__ import annotations

import numpy as np

from twoscale.cli.main import main


def _scene(tmp_path):
    y, x = np.mgrid[0:60, 0:60] * 0.25
    heights = np.exp(-((x - 7.5) ** 2 + (y - 7.5) ** 2) / 8.0)  # one smooth bump, mm
    np.save(tmp_path / "bump.npy", heights)
    scene = tmp_path / "bump.toml"
    scene.write_text(
        '[material]\nE = 10.0\nnu = 0.5\n[load]\ntotal = 1.0\n[surface]\nfile = "bump.npy"\nspacing = 0.25\n'
        "law_cache = false\n"
    )
    return scene


def test_surface_reruns_into_its_own_folder_with_overwrite(tmp_path, capsys):
    scene, out = _scene(tmp_path), tmp_path / "seg"
    assert main(["surface", str(scene), "--out", str(out), "--no-laws", "--quiet"]) == 0
    first = (out / "segmentation.csv").read_text()
    assert main(["surface", str(scene), "--out", str(out), "--no-laws", "--quiet"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert main(["surface", str(scene), "--out", str(out), "--no-laws", "--quiet", "--overwrite"]) == 0
    assert (out / "segmentation.csv").read_text() == first
    (out / "notes.txt").write_text("mine")
    assert main(["surface", str(scene), "--out", str(out), "--no-laws", "--quiet", "--overwrite"]) == 2
    assert (out / "notes.txt").read_text() == "mine" and (out / "segmentation.csv").exists()
