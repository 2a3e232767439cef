"""Regenerate the gallery: every figure the command line writes, made by the current tool.

Run from anywhere (about 3-5 minutes; the first finite-block run builds and caches its
FEM correction, about 1.2 GB at peak):

    python docs/gallery/make_gallery.py

It runs the shipped examples through ``twoscale solve``, ``surface``, ``compare``,
``study`` and ``paper --quick`` in a temporary folder, copies each PNG into
``docs/gallery/img/`` (named ``<command>_<example>_<file>``), rewrites
``docs/gallery/index.md`` with one section per command, and copies the seven-sphere
pressure map to ``docs/img/tour_pressure.png`` (the README's tour picture).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
IMG = ROOT / "docs" / "gallery" / "img"
INDEX = ROOT / "docs" / "gallery" / "index.md"

#: (command line after ``twoscale``, folder written, section, [(file, caption), ...])
RUNS = [
    (
        ["solve", "examples/paper_seven_spheres.toml"],
        "solve_seven",
        "twoscale solve: the paper's seven spheres",
        [
            (
                "pressure.png",
                (
                    "Pressure map: every loaded tip marked and numbered as in `asperities.csv`; the title "
                    "names the scene and the body, the load, the peak and how many tips carry load."
                ),
            ),
            ("forces.png", "Force per asperity: the macro step's estimate beside the force of the final pressure."),
        ],
    ),
    (
        ["solve", "examples/road/road.toml"],
        "solve_road",
        "twoscale solve: a road texture (100 stones)",
        [
            (
                "pressure.png",
                (
                    "With many tips only the loaded ones get a cross and the ten most loaded a number. Stones "
                    "cut by the map's edge carry a punch corner's peak (20 MPa here): the colour scale ends at "
                    "the 99th percentile of the loaded cells instead, and the colour bar and title give the "
                    "peak."
                ),
            ),
            (
                "forces.png",
                (
                    "Above 30 tips: the force histogram, and the loaded tips coloured by force, the ten most "
                    "loaded numbered."
                ),
            ),
        ],
    ),
    (
        ["surface", "examples/road/road.toml"],
        "surface_road",
        "twoscale surface: segmenting a height map",
        [
            (
                "segmentation.png",
                (
                    "Summits (red) and their watershed basins (orange boundaries) over the heights; the "
                    "ten highest summits numbered as in `asperities.csv`."
                ),
            )
        ],
    ),
    (
        ["compare", "examples/S1.toml", "--loads", "50"],
        "compare_S1",
        "twoscale compare: half-space against the block",
        [
            ("forces_50N.png", "Force per asperity on each body."),
            ("maps_50N.png", "Pressure maps on one colour scale; each panel names its body."),
            (
                "sensor_50N.png",
                "The same pressure averaged on the sensor's cells (what a pressure-sensitive film sees).",
            ),
            (
                "difference_50N.png",
                (
                    "Each block's tip forces minus the half-space's; the title gives the largest "
                    "change, its tip, and its share of the half-space's largest tip force."
                ),
            ),
        ],
    ),
    (
        ["study", "examples/study.toml", "--workers", "0"],
        "study_S2",
        "twoscale study: S2 on two bodies, two loads, three positions",
        [
            ("figures/load_approach_S2.png", "Total load and contact area against the approach, one line per body."),
            (
                "figures/asperity_forces_S2_block.png",
                "Each tip's force against the total load (the ten most loaded, one colour each).",
            ),
            ("figures/track_S2_block.png", "Tip forces along the positions of the track, the total on the right axis."),
            ("figures/indicators_S2.png", "e_M and e_m of the block against the half-space at each load."),
        ],
    ),
    (
        ["paper", "--quick"],
        "paper",
        "twoscale paper: the paper's numerical study",
        [
            (
                "fig3_two_maps.png",
                "Two spheres: p / p_m at three spacings (the paper's Fig. 3; dotted: the spheres' bases).",
            ),
            ("fig4_seven_maps.png", "Seven spheres (Fig. 4)."),
            ("fig5_profiles.png", "Pressure along a line through the upper asperity (Fig. 5)."),
            ("fig6_errors.png", "Errors of the two-scale pressure against the reference, and the sweeps (Fig. 6)."),
        ],
    ),
    (
        ["solve", "examples/creep/seven_spheres.toml"],
        "solve_creep",
        "twoscale solve: a load history on viscoelastic rubber",
        [
            (
                "history.png",
                (
                    "Load, approach, contact area and the most loaded tips' forces against time: a step load "
                    "held for 1,000 s, on a log time axis (linear when a late segment, such as an unloading "
                    "after a hold, would be a sliver of it)."
                ),
            )
        ],
    ),
    (
        ["solve", "examples/rolling/tyre.toml"],
        "solve_tyre",
        "twoscale solve: a road rolling under a slick tyre",
        [
            (
                "signals.png",
                (
                    "The approach (the load is held), the contact area and the drag against time, the drag's "
                    "mean dashed (on this elastic tread about 0.1 % of the 300 N load)."
                ),
            ),
            ("bands.png", "Third-octave levels of the approach; the 60 mm run resolves the 2,500 Hz band only."),
            (
                "space_time.png",
                "The pressure summed across y at every shift of the road: each stone crossing the footprint draws a line.",
            ),
        ],
    ),
]


def run(args: list, out: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    cmd = [sys.executable, "-m", "twoscale", *args, "--out", str(out), "--quiet"]
    print("twoscale", " ".join(args), flush=True)
    done = subprocess.run(cmd, cwd=ROOT, env=env, check=False)
    if done.returncode not in (0, 1):  # 1: ran, some case did not converge (still drawn)
        raise SystemExit(f"failed ({done.returncode}): {' '.join(cmd)}")


def main() -> None:
    lines = [
        "# Gallery: every figure the program writes",
        "",
        "Made by the current tool from the shipped examples; regenerate them with",
        "`python docs/gallery/make_gallery.py`. Each PNG also carries, in its metadata, the",
        "program version, its title and the scene it shows.",
        "",
    ]
    IMG.mkdir(parents=True, exist_ok=True)
    for old in IMG.glob("*.png"):
        old.unlink()
    with tempfile.TemporaryDirectory() as tmp:
        for args, folder, section, figures in RUNS:
            out = Path(tmp) / folder
            run(args, out)
            lines += [f"## {section}", "", f"`twoscale {' '.join(args)} --out DIR`", ""]
            for name, caption in figures:
                target = IMG / f"{folder}_{Path(name).name}"
                shutil.copyfile(out / name, target)
                lines += [f"### `{name}`", "", caption, "", f"![{name}](img/{target.name})", ""]
            if folder == "solve_seven":
                shutil.copyfile(out / "pressure.png", ROOT / "docs" / "img" / "tour_pressure.png")
    INDEX.write_text("\n".join(lines), encoding="utf-8")
    print(f"wrote {INDEX.relative_to(ROOT)} and {len(list(IMG.glob('*.png')))} figures")


if __name__ == "__main__":
    main()
