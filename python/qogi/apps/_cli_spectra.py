"""``qogi xsec`` and ``qogi hitran ...``: the spectroscopy commands."""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import numpy as np

from .. import _engine
from ..errors import UsageError
from ..files import atomic_path, check_outputs
from ..physics.spectra import (
    bundled_hitran_dir,
    bundled_line_lists,
    cross_section,
    fetch_hitran,
    find_line_lists,
    hitran_search_path,
    load_line_list,
)
from ._cli_args import fraction, nonnegative_float, positive_float


def _cutoff(text: str):
    if text.lower() == "hapi":
        return "hapi"
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--cutoff must be 'hapi' or a wing half-width in cm-1; got {text!r}"
        ) from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"--cutoff in cm-1 must be > 0; got {text}")
    return value


def cmd_xsec(args: argparse.Namespace) -> int:

    if args.out:
        check_outputs({"--out": args.out}, inputs=args.line_list or ())
        if pathlib.Path(args.out).suffix.lower() not in (".npz", ".csv"):
            raise UsageError(f"--out {args.out}: give a .npz or .csv file name")
    lo, hi = args.range
    if not hi > lo:
        raise UsageError(f"--range {lo:g} {hi:g}: MAX must be greater than MIN")
    n_points = (hi - lo) / args.step + 1
    if n_points > 5e7:
        raise UsageError(
            f"--range {lo:g} {hi:g} with --step {args.step:g} is {n_points:.3g} "
            "points (at most 5e7); use a coarser --step or a narrower range"
        )
    try:
        _engine.molecule_id(args.species)
    except ValueError as e:
        raise UsageError(str(e)) from None
    nu0, step, n = _engine.grid_from_range(lo, hi, args.step)
    nu = nu0 + step * np.arange(n)
    try:
        lines = load_line_list(args.species, args.line_list or None)
    except FileNotFoundError as e:
        raise UsageError(str(e).strip("'\"")) from None
    sigmas = []
    t0 = time.perf_counter()
    for t in args.temperature:
        sigmas.append(
            cross_section(
                args.species, nu, t, args.pressure, lines, args.cutoff, args.self_fraction
            )
        )
    dt = time.perf_counter() - t0
    sigma = np.array(sigmas) if len(sigmas) > 1 else sigmas[0]
    meta = {
        "species": args.species.upper(),
        "temperature_K": args.temperature,
        "pressure_Pa": args.pressure,
        "self_fraction": args.self_fraction,
        "cutoff": args.cutoff,
        "line_files": list(lines.sources),
        "lines": len(lines),
        "units": {"nu_cm1": "cm-1", "sigma": "cm2/molecule"},
    }
    print(
        f"{args.species}: {len(lines)} lines, {n} points {nu[0]:.4f}-{nu[-1]:.4f} cm-1, "
        f"T = {', '.join(f'{t:g}' for t in args.temperature)} K, "
        f"p = {args.pressure:g} Pa: peak sigma {np.max(sigma):.4e} cm2/molecule "
        f"({dt * 1e3:.0f} ms)"
    )
    if args.out:
        out = pathlib.Path(args.out)
        with atomic_path(out) as tmp:
            if out.suffix.lower() == ".csv":
                cols = np.column_stack([nu, *np.atleast_2d(sigma)])
                header = "nu_cm1," + ",".join(
                    f"sigma_{t:g}K_cm2_per_molecule" for t in args.temperature
                )
                np.savetxt(tmp, cols, delimiter=",", header=header, comments="", fmt="%.10g")
            else:
                np.savez_compressed(
                    tmp,
                    nu_cm1=nu,
                    sigma_cm2_per_molecule=sigma,
                    temperature_K=np.asarray(args.temperature),
                    meta=np.array(json.dumps(meta)),
                )
        print(f"wrote {out}")
    return 0


def cmd_hitran_list(args: argparse.Namespace) -> int:

    bundled = bundled_hitran_dir()
    print("shipped with qogi (used when no folder above it in the search path has the species):")
    for e in bundled_line_lists():
        isos = ",".join(str(i) for i in e["isotopologues"])
        print(
            f"  {e['file']}: {e['species']} isotopologue(s) {isos}, {e['lines']} lines, "
            f"{e['nu_min_cm1']:.2f}-{e['nu_max_cm1']:.2f} cm-1, {e['edition']}"
        )
        print(f"      from {e['source']}")
        print(f"      cite {e['citation']}; sha256 of the records {e['sha256_records'][:16]}...")
    print("search path (first folder holding a species' files wins):")
    for p in hitran_search_path(args.path):
        note = "  (shipped with qogi)" if p == bundled else ("" if p.is_dir() else "  (missing)")
        print(f"  {p}{note}")
    species = args.species or sorted(
        {_engine.molecule_formula(i["molecule"]) for i in _engine.isotopologues()}
    )
    found_any = False
    for sp in species:
        try:
            files = find_line_lists(sp, args.path)
        except FileNotFoundError:
            if args.species:
                print(f"{sp}: no line list found")
            continue
        found_any = True
        lines = load_line_list(sp, files)
        print(f"{sp}: {len(lines)} lines in use from {len(files)} file(s), first has priority")
        for k, f in enumerate(lines.sources):
            print(f"  [{k + 1}] {f}")
            for mol, iso, a, b, src in lines.coverage:
                if src == k and _engine.molecule_formula(mol).upper() == sp.upper():
                    print(f"      isotopologue {iso}: {a:.4f}-{b:.4f} cm-1")
        iso_ids, counts = np.unique(lines.isotopologue, return_counts=True)
        print(
            "  lines in use per isotopologue: "
            + ", ".join(f"{i}: {c}" for i, c in zip(iso_ids, counts))
        )
    if not found_any:
        print("no line lists found; see `qogi hitran fetch --help`")
    return 0


def cmd_hitran_fetch(args: argparse.Namespace) -> int:

    isos = [int(v) for v in args.isotopologues.split(",")] if args.isotopologues else None
    try:
        path = fetch_hitran(args.species, args.range[0], args.range[1], isos, args.dir)
    except ConnectionError as e:
        print(f"qogi hitran fetch: {e}", file=sys.stderr)
        return 1
    print(f"wrote {path}")
    return 0


def _add_range(parser) -> None:
    """The wavenumber range option (xsec and hitran fetch)."""
    parser.add_argument(
        "--range",
        nargs=2,
        type=nonnegative_float,
        required=True,
        metavar=("MIN", "MAX"),
        help="wavenumber range [cm-1]",
    )


def add_commands(sub) -> None:
    """Registers the spectroscopy commands on the CLI's subparsers."""
    x = sub.add_parser(
        "xsec",
        help="absorption cross-section of a gas from HITRAN lines",
        description="Voigt absorption cross-section sigma(nu) [cm2/molecule] of a gas from "
        "its HITRAN line list (see qogi.cross_section).",
    )
    x.add_argument("species", help="gas formula, e.g. CH4, CO2, H2O")
    _add_range(x)
    x.add_argument(
        "--step", type=positive_float, default=0.01, help="grid step [cm-1] (default 0.01)"
    )
    x.add_argument(
        "--temperature",
        type=positive_float,
        nargs="+",
        default=[296.0],
        help="gas temperature(s) [K] (default 296)",
    )
    x.add_argument(
        "--pressure",
        type=positive_float,
        default=101325.0,
        help="total pressure [Pa] (default 101325)",
    )
    x.add_argument(
        "--self-fraction",
        type=fraction,
        default=0.0,
        help="absorber mole fraction for self-broadening (default 0)",
    )
    x.add_argument(
        "--cutoff",
        type=_cutoff,
        default="hapi",
        help="line wings: 'hapi' (50 half-widths, default) or a half-width in cm-1",
    )
    x.add_argument(
        "--line-list",
        nargs="+",
        default=None,
        metavar="PATH",
        help="line files or folders (default: the usual search path)",
    )
    x.add_argument("--out", help="write nu and sigma to this .npz or .csv file")
    x.set_defaults(func=cmd_xsec)

    h = sub.add_parser("hitran", help="find or download HITRAN line lists")
    hs = h.add_subparsers(dest="hitran_command", metavar="ACTION")
    ls = hs.add_parser("list", help="show the line lists qogi finds")
    ls.add_argument("species", nargs="*", help="species to show (default: all with data)")
    ls.add_argument("--path", nargs="+", default=None, help="extra folders to search first")
    ls.set_defaults(func=cmd_hitran_list)
    f = hs.add_parser("fetch", help="download lines from HITRANonline (needs the internet)")
    f.add_argument("species")
    _add_range(f)
    f.add_argument(
        "--isotopologues",
        help="comma-separated local isotopologue numbers (default: all qogi knows)",
    )
    f.add_argument("--dir", help="folder to save into (default: the per-user cache)")
    f.set_defaults(func=cmd_hitran_fetch)
    h.set_defaults(func=lambda a: (h.print_help(), 2)[1])
