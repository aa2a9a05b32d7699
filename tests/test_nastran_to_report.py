"""The documented path from a NASTRAN model to a report with no Python
(docs/nastran.md): every step a ``jitterfmu`` command on files a user has.

The user's files are made here: the ten-bay truss as a NASTRAN deck (BDF + OP4, as in
tests/structfmu/test_nastran.py) and the shipped strain-feedback laws as MATLAB's
``ssdata`` would save them (``A, B, C, D, Ts`` with names, units, limits and
``delayed = 1``, the paper's Eq. 11).  The reference is the same campaign on the suite's
own FMUs: the imported structure and the laws from ``.mat`` files must give its budget.
"""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
import pytest
import scipy.io

from ctrlfmu.designs import design
from orchestrator.cli import main

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_nastran_deck_and_mat_laws_to_a_report(tmp_path, suite_fmus, suite_fmu_dir, capsys):
    pytest.importorskip("pyNastran")
    from structfmu import nastran as nas
    from tests.orchestrator.test_truss10_campaign import FMUS
    from tests.structfmu.test_nastran import ROTATED, cli_args, strut_truss

    suite_fmus(*FMUS)
    bdf, op4 = nas.write_truss_deck(strut_truss(), tmp_path / "truss10.bdf",
                                    tmp_path / "truss10.op4", units="in-lbf-s",
                                    rotated=ROTATED)
    for name in ("truss10_strain_diag", "truss10_strain_long"):
        law = design(name)
        scipy.io.savemat(tmp_path / f"{name}.mat", {
            "A": law.A, "B": law.B, "C": law.C, "D": law.D, "Ts": law.dt, "delayed": 1,
            "InputName": np.array(list(law.inputs), dtype=object),
            "InputUnit": np.array(list(law.input_units), dtype=object),
            "u_min": law.u_min, "u_max": law.u_max})
    mine = tmp_path / "myfmus"
    # the suite's stacks and excitation, as `jitterfmu build` puts them in a user's folder
    # (on a fresh clone nothing else is on the search path)
    mine.mkdir()
    kept = sorted(n for n in FMUS if not n.startswith(("truss10_structure", "controller_")))
    for n in kept:
        __import__("shutil").copy2(suite_fmu_dir / f"{n}.fmu", mine / f"{n}.fmu")
    npz = tmp_path / "truss10.npz"
    steps = [
        ["import-nastran", str(bdf), "--op4", str(op4), *cli_args("in-lbf-s"),
         "--zeta-band", "0:9=0.0018", "--zeta-band", "9:9.9=0.004", "--out", str(npz)],
        ["build", "--structure", str(npz), "--out", str(mine), "--native"],
        *[["build", "--controller", str(tmp_path / f"{n}.mat"), "--model", f"controller_{n}",
           "--out", str(mine), "--native"]
          for n in ("truss10_strain_diag", "truss10_strain_long")],
        ["campaign", str(ROOT / "campaigns" / "truss10_quick.toml"), "--fmu-dir", str(mine),
         "--out", str(tmp_path / "mine"), "--workers", "0", "--quiet"],
        ["report", str(tmp_path / "mine")],
        ["campaign", str(ROOT / "campaigns" / "truss10_quick.toml"), "--fmu-dir",
         str(suite_fmu_dir), "--out", str(tmp_path / "suite"), "--workers", "0", "--quiet"],
    ]
    for args in steps:
        assert main(args) == 0, (args, capsys.readouterr().err)
    assert {p.name for p in mine.glob("*.fmu")} == {
        "truss10_structure.fmu", "controller_truss10_strain_diag.fmu",
        "controller_truss10_strain_long.fmu"} | {f"{n}.fmu" for n in kept}
    assert "<table class=\"verdict\">" in (tmp_path / "mine" / "report.html").read_text()

    def budget(folder):
        rows = pq.read_table(folder / "summary.parquet").to_pylist()
        return {(r["case"], r["instrument"], r["axis"], r["metric"], r["window"]): r["value"]
                for r in rows}

    got, want = budget(tmp_path / "mine"), budget(tmp_path / "suite")
    assert got.keys() == want.keys() and len(got) > 10
    for key, value in want.items():   # the import gives the built-in model to 1e-12
        assert got[key] == pytest.approx(value, rel=1e-6), key
