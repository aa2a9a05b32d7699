"""``jitterfmu import-nastran``: a reduced structure model from a NASTRAN BDF + OP4/OP2."""

from __future__ import annotations

import argparse
import warnings

COMMAND = "import-nastran"
HELP = ("reduce a NASTRAN model (BDF + OP4 mass/stiffness, or a SOL 103 OP2) to a "
        "structure model .npz: modes + static Ritz vectors at actuators and loads")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``jitterfmu import-nastran``."""
    parser.add_argument("bdf", help="bulk data file: grids, coordinate systems, elements, SPCs")
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--op4", help="OUTPUT4 file with the stiffness and mass matrices "
                     "(KGG/MGG, or KAA/MAA with --dof-map)")
    src.add_argument("--op2", help="OP2: a SOL 103 run (eigenvalues and eigenvectors, and "
                     "residual vectors of a RESVEC run as the Ritz block), or stiffness and "
                     "mass matrix blocks (KAA/MAA, KGG/MGG, ... written by OUTPUT2)")
    src.add_argument("--dmig", help="DMIG punch file (PARAM,EXTOUT,DMIGPCH) with the stiffness "
                     "and mass on the DOFs its cards name")
    parser.add_argument("--units", required=True, choices=["SI", "in-lbf-s", "mm-t-s"],
                        help="unit system of the BDF, the matrices and explicit stack values")
    parser.add_argument("--modes", type=int, required=True, metavar="N",
                        help="eigenvectors to keep (rigid-body modes included)")
    parser.add_argument("--out", required=True, help="reduced model file to write (.npz)")
    parser.add_argument("--actuator", action="append", default=[],
                        metavar="EID=PRESET[,name=N][,gauge=EID]",
                        help="replace an axial member (CROD, CONROD, CBAR, CBEAM) by a piezo "
                        "stack: a preset (P-243.30, P-243.40, P-845.37) or k_e=..,ch=..,mass=.. "
                        "in the declared units; input fc_N, outputs elong_N and strain_N")
    parser.add_argument("--sensor", action="append", default=[], metavar="NAME=GRID:COMP[:KIND]",
                        help="output at one DOF (component in the grid's CD frame); KIND disp "
                        "(default) or accel")
    parser.add_argument("--load", action="append", default=[], metavar="NAME=GRID:COMP",
                        help="force (components 1-3, N) or moment (4-6, N m) input at one DOF")
    parser.add_argument("--los", action="append", default=[], metavar="NAME=GRID[,GRID,...]",
                        help="line of sight NAME_roll/_pitch/_yaw: rotations of one grid, or "
                        "the rigid rotation of three or more grids (an optical bench)")
    parser.add_argument("--ritz", choices=["all", "actuators", "none"], default=None,
                        help="static Ritz vectors for actuators and loads (default with --op4), "
                        "actuators only, or none (the only choice with --op2)")
    parser.add_argument("--shift", type=float, default=None,
                        help="eigensolver shift ((rad/s)^2); negative (e.g. -1) for a free-free "
                        "model with rigid-body modes (default: 0, a constrained model)")
    parser.add_argument("--zeta", type=float, default=0.005,
                        help="modal damping ratio of every mode (default 0.005)")
    parser.add_argument("--zeta-band", action="append", default=[], metavar="F1:F2=ZETA",
                        help="damping ratio of the modes between F1 and F2 Hz (repeatable)")
    parser.add_argument("--zeta-ritz", type=float, default=0.02,
                        help="damping ratio of the Ritz block (default 0.02)")
    parser.add_argument("--dof-map", default=None,
                        help="text file 'ID COMPONENT' per matrix row (default: the g-set)")
    parser.add_argument("--k-name", default=None,
                        help="stiffness matrix name in the OP4, OP2 or DMIG file (default: "
                        "the one of KGG, KNN, KFF, KAA there, else its one square K* matrix)")
    parser.add_argument("--m-name", default=None,
                        help="mass matrix name in the OP4, OP2 or DMIG file (default: the "
                        "one of MGG, MNN, MFF, MAA there, else its one square M* matrix)")
    parser.add_argument("--name", default=None, help="model name (default: the BDF's stem)")
    parser.add_argument("--include-dir", action="append", default=[], metavar="DIR",
                        help="a folder besides the BDF's own that its INCLUDE statements may "
                        "name (repeatable); any other INCLUDE is refused")
    parser.add_argument("--boundary", choices=["free", "fixed"], default=None,
                        help="Craig-Bampton model (a q-set in the BDF): boundary DOFs free "
                        "(default) or fixed (the fixed-interface modes)")


def run(args: argparse.Namespace) -> int:
    """Import, reduce and save; print one summary line."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from structfmu import nastran
    from structfmu.reduce import Damping

    bands = [_band(b) for b in args.zeta_band]
    from ..progress import stage
    from . import report_warnings
    from ._options import shown

    matrices = "OP4" if args.op4 else "OP2" if args.op2 else "DMIG"
    stage(f"import-nastran {shown(args.bdf)}: reading the deck and the {matrices} file, "
          f"reducing to {args.modes} modes")

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", nastran.NastranWarning)
        try:
            model = _import(nastran, Damping, args, bands)
        finally:   # what the deck said is shown even when the import then fails
            report_warnings(caught)
    path = model.save(args.out)
    f = model.frequencies_hz
    print(f"{path}: {model.n_modes} modes ({f.min():.4g}-{f.max():.4g} Hz) + {model.n_ritz} "
          f"Ritz vectors, {model.n_inputs} inputs, {model.n_outputs} outputs, from "
          f"{model.meta['n_dof']} DOFs")
    return 0


def _import(nastran, Damping, args, bands):
    """The library call the options describe."""
    return nastran.import_nastran(
        args.bdf, units=args.units, op4=args.op4, op2=args.op2, dmig=args.dmig,
        n_modes=args.modes, boundary=args.boundary,
        actuators=[nastran.parse_actuator(a, args.units) for a in args.actuator],
        sensors=[nastran.parse_point(s) for s in args.sensor],
        loads=[nastran.parse_point(s, "force") for s in args.load],
        los=[nastran.parse_los(s) for s in args.los], ritz=args.ritz, shift=args.shift,
        damping=Damping(zeta=args.zeta, zeta_ritz=args.zeta_ritz), zeta_bands=bands,
        dof_map=args.dof_map, k_name=args.k_name, m_name=args.m_name, name=args.name,
        include_dirs=args.include_dir)


def _band(text: str):
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from structfmu.nastran import NastranError

    span, sep, zeta = text.partition("=")
    lo, sep2, hi = span.partition(":")
    try:
        if not (sep and sep2):
            raise ValueError
        return float(lo), float(hi), float(zeta)
    except ValueError:
        raise NastranError(f"damping band {text!r}: expected F1:F2=ZETA (Hz, Hz, ratio)") from None
