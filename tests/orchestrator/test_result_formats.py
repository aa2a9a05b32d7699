"""Results in the formats people load: units in Parquet and CSV, MATLAB files, files the
group can read, and one default output folder."""

import json
import os
import stat

import numpy as np
import pytest
import scipy.io
import tomli_w

from orchestrator import run_scenario
from orchestrator.cli import main
from orchestrator.results import read_table, read_units

pytestmark = pytest.mark.filterwarnings(
    "ignore::orchestrator.cosim.UnconnectedInputWarning")

UNITS = {"time": "s", "i.x": "1", "i.xm": "m"}


def scenario():
    """x(t) = t (unit 1) and its copy xm (unit m)."""
    return {
        "experiment": {"stop": 0.02, "output_interval": 1e-3},
        "fmus": {"i": {"fmu": "MtIntegrator", "period": 1e-3, "parameters": {"u": 1.0}}},
        "record": {"variables": ["i.x", "i.xm"]},
    }


@pytest.mark.parametrize("fmt", ["parquet", "csv", "mat"])
def test_every_format_carries_the_units_and_reads_back(fmu_dir, tmp_path, fmt):
    res = run_scenario(scenario(), tmp_path / fmt, fmu_dir=fmu_dir, fmt=fmt)
    path = tmp_path / fmt / f"results.{fmt}"
    assert res.metadata["units"] == UNITS and res.metadata["format"] == fmt
    back = read_table(path)      # a pandas DataFrame with the FMUs' units
    assert list(back) == ["time", "i.x", "i.xm"]
    for k in back:
        np.testing.assert_array_equal(back[k], res.table[k])   # lossless in every format
    assert back.attrs["units"] == UNITS
    if fmt == "parquet":
        import pyarrow.parquet as pq

        assert read_units(path) == UNITS
        assert json.loads(pq.read_schema(path).metadata[b"units"]) == UNITS
    elif fmt == "csv":
        assert path.read_text().splitlines()[0] == "time [s],i.x [1],i.xm [m]"
        assert read_units(path) == UNITS
    else:   # what MATLAB's load gives: results.i.xm, results.units.i.xm
        m = scipy.io.loadmat(path, simplify_cells=True)
        np.testing.assert_array_equal(m["i"]["xm"], res.table["i.xm"])
        np.testing.assert_array_equal(m["time"], res.table["time"])
        assert m["units"]["i"]["xm"] == "m" and m["units"]["time"] == "s"


def test_result_files_are_readable_by_the_group(fmu_dir, tmp_path):
    old = os.umask(0o022)
    os.umask(old)
    run_scenario(scenario(), tmp_path / "o", fmu_dir=fmu_dir)
    for name in ("results.parquet", "run.json"):
        mode = stat.S_IMODE((tmp_path / "o" / name).stat().st_mode)
        assert mode == 0o666 & ~old, oct(mode)
        if not old & 0o040:
            assert mode & 0o040   # the temporary file's private 0600 is gone


def test_run_writes_mat_from_the_cli_and_defaults_to_out(fmu_dir, tmp_path, monkeypatch,
                                                         capsys):
    scen = tmp_path / "tiny.toml"
    scen.write_text(tomli_w.dumps(scenario()))
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(scen), "--fmu-dir", str(fmu_dir), "--quiet",
                 "--format", "mat"]) == 0
    out = capsys.readouterr().out
    assert "21 rows x 2 variables in out/tiny/results.mat" in out
    assert (tmp_path / "out/tiny/results.mat").is_file()


def test_a_table_of_every_column_kind_reads_back_and_writing_it_imports_no_pandas(tmp_path):
    """Floats (strided too), integers, a big-endian column, booleans and strings read back
    equal with their units; a child process that writes a table of numbers has not
    imported pandas (0.17 s of every short command)."""
    import subprocess
    import sys

    from orchestrator.results import write_table

    t = np.linspace(0.0, 1.0, 11)
    table = {"time": t, "a.x": np.arange(22.0)[::2], "a.n": np.arange(11),
             "a.b": np.arange(11.0).astype(">f8"), "a.on": t > 0.5,
             "a.s": np.array([f"s{i}" for i in range(11)])}
    path = write_table(table, tmp_path / "t.parquet", units={"time": "s", "a.x": "m"})
    back = read_table(path)
    for k, v in table.items():
        np.testing.assert_array_equal(np.asarray(back[k]), v)
    assert read_units(path) == {"time": "s", "a.x": "m"}
    code = ("import sys, numpy as np; from orchestrator.results import write_table; "
            f"write_table({{'time': np.arange(3.0), 'x': np.arange(3)}}, {str(tmp_path / 'u.parquet')!r}); "
            "print('pandas' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"
