"""``jitterfmu build``: build and validate the project's FMUs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

COMMAND = "build"
HELP = "build every FMU of the project (or the named ones), native and Python, and validate"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``jitterfmu build``."""
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="FMU folder (default: fmus/, with --fmi 3 fmus/fmi3/): the "
                        "native FMUs in it, their Python twins in its python/ subfolder")
    parser.add_argument("--fmi", type=int, choices=(2, 3), default=2,
                        help="FMI version of the native FMUs (default 2); 3 writes FMI 3.0 "
                        "co-simulation FMUs from the same C kernels, native only "
                        "(docs/native-fmus.md)")
    parser.add_argument("--model", action="append", metavar="NAME",
                        help="modelIdentifier to build (repeatable; default: all); with "
                        "--structure or --controller, the identifier of that FMU")
    one = parser.add_mutually_exclusive_group()
    one.add_argument("--structure", metavar="MODEL.npz",
                     help="build only a structure FMU from a reduced model file (e.g. from "
                     "'jitterfmu import-nastran'), named <stem>_structure unless --model")
    one.add_argument("--controller", metavar="LAW",
                     help="build only a controller FMU from a state-space file (.mat, .npz "
                     "or .csv holding A, B, C, D, Ts as MATLAB's ssdata gives them, with "
                     "InputName/OutputName) or a law written by ctrlfmu.law.save_law; "
                     "named controller_<law name> unless --model (docs/controllers.md)")
    parser.add_argument("--period", type=float, metavar="SECONDS", default=None,
                        help="with --controller: the FMU's period, at which a continuous "
                        "state-space (Ts = 0) is discretised by a zero-order hold (default: "
                        "none; a discrete law runs at its own Ts)")
    parser.add_argument("--force", action="store_true",
                        help="rebuild every FMU asked for (default: keep those in --out built "
                        "from the same sources, content-keyed, and say which lack a win64 "
                        "binary)")
    only = parser.add_mutually_exclusive_group()
    only.add_argument("--native", action="store_true",
                      help="only the native (C99) FMUs, into --out itself "
                      "(docs/native-fmus.md)")
    only.add_argument("--python", action="store_true",
                      help="only the Python (pythonfmu) FMUs, into --out/python/")


def run(args: argparse.Namespace) -> int:
    """Build; return 0, or 1 when an FMU has validation problems."""
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from fmutools import PYTHON_SUBDIR
    from fmutools.ensure import record_built
    from fmutools.registry import build_all
    from nativefmu.build import build_all_native, build_native_structure
    from structfmu.fmuspec import build_structure_fmu

    fmi = args.fmi
    if fmi == 3 and args.python:
        raise ValueError("--python builds the Python FMUs, which are FMI 2.0 only; drop "
                         "--python or --fmi 3")
    out = Path(args.out) if args.out else Path("fmus") / ("fmi3" if fmi == 3 else "")
    py_dir = out / PYTHON_SUBDIR
    single = args.structure or args.controller
    if single and args.model and len(args.model) > 1:
        option = "--structure" if args.structure else "--controller"
        raise ValueError(f"{option} builds one FMU; give at most one --model")
    name = args.model[0] if (single and args.model) else None
    if args.period is not None and not args.controller:
        raise ValueError("--period is the period of a --controller state-space; give "
                         "--controller LAW or drop --period")
    if not single:   # the long builds; a single FMU says what it built when done
        from orchestrator.progress import stage

        from ._options import shown

        what = ", ".join(args.model) if args.model else "every FMU of the project"
        stage(f"build {what} (FMI {fmi}) into {shown(out)}")
    if args.controller:   # with --fmi 3 the Python twin stays in a temporary folder
        return _report(*_build_controller(args.controller, out, py_dir, name, args))
    problems, built, skipped = [], [], ()
    if fmi == 3:
        return _report(*_build_fmi3(args, out, name))
    todo_py, todo_native = (None, None) if args.structure else _stale(args, out, py_dir)
    if not args.native:
        if args.structure:
            report = build_structure_fmu(args.structure, py_dir, name)
            print(f"{report.fmus[0]} {'ok' if not report.problems else 'has problems'}")
        elif todo_py:
            report = build_all(py_dir, todo_py, progress=print)
            record_built(py_dir, [p.stem for p in report.fmus], "python")
        if args.structure or todo_py:
            problems += report.problems
            built += report.fmus
        else:
            built.append(py_dir)      # every one kept
    if not args.python:
        if args.structure:
            report = build_native_structure(args.structure, out, name)
            print(f"{report.fmus[0]} (native) {'ok' if not report.problems else 'has problems'}")
        elif todo_native:
            report = build_all_native(out, todo_native, progress=print,
                                      python_dir=None if args.native else py_dir)
            record_built(out, [p.stem for p in report.fmus], "native")
        if args.structure or todo_native:
            problems += report.problems
            built += report.fmus
            skipped = report.skipped
        else:
            built.append(out)         # every one kept
    if skipped:
        print(f"no native kernel for {', '.join(skipped)}; their Python FMUs are in "
              f"{py_dir}", file=sys.stderr)
    return _report(problems, built)


def _names(args) -> list[str]:
    """The registry FMUs ``build`` is asked for (``--model``, or all)."""
    from fmutools.registry import collect_specs

    return [s.model_identifier for s in collect_specs(args.model)]


def _stale(args, out: Path, py_dir: Path) -> tuple[list, list]:
    """The FMUs to build, Python and native: all with ``--force``, else those not already
    in the folders from today's sources (content-keyed stamps); says what is kept."""
    from fmutools.ensure import current_fmus
    from nativefmu.build import mingw_compiler

    names = _names(args)
    if not names:
        raise ValueError("no FMU to build: no package provides an fmuspec module")
    if args.force:
        return names, names
    py_ok = [] if args.native else current_fmus(py_dir, names, "python")
    native_ok = [] if args.python else current_fmus(out, names, "native")
    kept = sorted(set(py_ok) | set(native_ok))
    todo_py = [n for n in names if n not in py_ok]
    todo_native = [n for n in names if n not in native_ok]
    if kept:
        print(f"kept {len(py_ok) + len(native_ok)} FMU(s) already built from these sources "
              f"in {out} ({', '.join(kept)}); --force rebuilds them")
    mingw = mingw_compiler()
    linux_only = [n for n in native_ok if not _has_binaries(out / f"{n}.fmu", mingw)]
    if linux_only:   # built for this machine alone (jitterfmu reproduce, make demo)
        print(f"{len(linux_only)} of them have no win64 binary (built for this machine "
              "only); --force adds it")
    return todo_py, todo_native


def _has_binaries(fmu: Path, mingw) -> bool:
    """A native FMU holds every binary this machine can build (win64 with a cross
    compiler)."""
    import zipfile

    if mingw is None:
        return True
    try:
        with zipfile.ZipFile(fmu) as z:
            return any(n.startswith("binaries/win64/") for n in z.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


def _build_fmi3(args, out: Path, name) -> tuple[list, list]:
    """``--fmi 3``: the FMI 3.0 native FMUs (their Python twins built in a temporary
    folder, for the model descriptions); returns (problems, built).  They are not
    stamped for ``ensure_fmus``, whose folders hold FMI 2.0 builds."""
    from nativefmu.build import build_all_native, build_native_structure

    if args.structure:
        report = build_native_structure(args.structure, out, name, fmi=3)
        print(f"{report.fmus[0]} (native, FMI 3.0) "
              f"{'ok' if not report.problems else 'has problems'}")
    else:
        report = build_all_native(out, args.model, progress=print, fmi=3)
        if report.skipped:
            print(f"no native kernel for {', '.join(report.skipped)}: no FMI 3.0 build",
                  file=sys.stderr)
    return list(report.problems), list(report.fmus)


def _build_controller(path, out: Path, py_dir: Path, name, args) -> tuple[list, list]:
    """``--controller``: the law file's Python FMU (in ``py_dir``) and native FMU (in
    ``out``), each validated; returns (problems, built)."""
    import tempfile

    from ctrlfmu.fmuspec import build_controller_fmu, controller_identifier, law_spec
    from ctrlfmu.statespace import read_controller
    from fmutools.validate import validate_fmu
    from nativefmu.build import build_native

    law = read_controller(Path(path), args.period)
    ident = controller_identifier(law, name)
    print(f"{ident}: {law.description}; {law.A.shape[0]} state(s), inputs "
          f"{', '.join(law.inputs)} -> outputs {', '.join(law.outputs)}")
    problems, built = [], []
    with tempfile.TemporaryDirectory(prefix="jitterfmu_ctrl_") as tmp:
        report = build_controller_fmu(law, tmp if args.native or args.fmi == 3 else py_dir,
                                      ident)
        twin = report.fmus[0]
        if not args.native and args.fmi == 2:
            print(f"{twin} {'ok' if not report.problems else 'has problems'}")
            problems += report.problems
            built.append(twin)
        if not args.python:
            native = build_native(law_spec(law, ident), out, python_fmu=twin, fmi=args.fmi)
            found = validate_fmu(native, strict=True)
            print(f"{native} (native) {'ok' if not found else 'has problems'}")
            problems += found
            built.append(native)
    return problems, built


def _report(problems, built) -> int:
    """Print the problems; 0 when every FMU built is valid."""
    for problem in problems:
        print(problem, file=sys.stderr)
    return 1 if problems or not built else 0
