"""Reproduce the paper's numerical study (figs. 3-6): CSV files and PNG figures."""
from __future__ import annotations

import argparse
import math
import pathlib
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``twoscale paper``."""
    parser.add_argument("--out", required=True, type=pathlib.Path, help="output folder (created)")
    parser.add_argument("--quick", action="store_true",
                        help="cells twice the paper's size (four times fewer), same d/2R values")
    parser.add_argument("--tol", type=float, default=1e-6,
                        help="eq. 9 tolerance on ||p^{m+1} - p^m|| / ||p^{m+1}|| (default 1e-6; the paper "
                             "writes eq. 9 with squared norms, so its epsilon is tol^2)")
    parser.add_argument("--reference", choices=("cg", "dense", "auto"), default="cg",
                        help="reference solver on the same lattice (default cg)")
    parser.add_argument("--no-figures", action="store_true", help="write the CSV files only")


def run(args: argparse.Namespace) -> int:
    """Run the study; 0 if every case converged and met the 0.1 % acceptance, else 1."""
    from ..study import run_study
    from ..study.output import write_csv

    if not (math.isfinite(args.tol) and args.tol > 0):
        print(f"error: --tol must be > 0, got {args.tol}", file=sys.stderr)
        return 2
    study = run_study(quick=args.quick, tol=args.tol, reference_method=args.reference,
                      progress=lambda text: print(text, file=sys.stderr))
    files = write_csv(study, args.out)
    if not args.no_figures:
        from ..study.figures import write_figures

        files += write_figures(study, args.out)
    ok = True
    print(f"{'layout':7s} {'d/2R':>6s} {'p0 err %':>9s} {'p err %':>9s} {'sweeps':>6s} {'t_2s s':>7s} {'t_ref s':>7s}")
    for layout, results in study.cases.items():
        for r in results:
            print(f"{layout:7s} {r.case.spacing:6g} {r.err_p0_percent:9.3f} {r.err_p_percent:9.2e} "
                  f"{r.sweeps:6d} {r.twoscale.timings_s['total']:7.2f} {r.ref.timings_s['wall']:7.2f}")
            ok &= bool(r.twoscale.converged and r.ref.converged and r.err_p_percent <= 0.1)
    print(f"acceptance 100 ||p - p_r|| / ||p_r|| <= 0.1 for every case: {'PASS' if ok else 'MISS'}")
    print(f"wrote {len(files)} files to {args.out}")
    return 0 if ok else 1
