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


def test_rows_table_is_pyarrows_from_pylist():
    """Rows of numbers, booleans and strings (unicode, empty, missing keys and None as
    nulls) give the table ``pyarrow.Table.from_pylist`` gives, and a type laid out by
    pyarrow (a list) still converts."""
    import pyarrow as pa

    from orchestrator.results import rows_table

    schema = pa.schema([("s", pa.string()), ("x", pa.float64()), ("n", pa.int64()),
                        ("ok", pa.bool_()), ("u", pa.uint8()), ("l", pa.list_(pa.int64()))])
    rows = [{"s": "α-case", "x": 1.5, "n": 3, "ok": True, "u": 7, "l": [1, 2]},
            {"s": "", "x": float("nan"), "n": -2, "ok": None, "u": 0, "l": []},
            {"x": None, "n": None, "ok": False, "extra": "ignored"},
            {"s": None, "x": -0.0, "n": 2**40, "ok": True, "u": 255, "l": None}]
    got = rows_table(rows, schema)
    want = pa.Table.from_pylist(rows, schema=schema)
    assert got.schema == want.schema
    assert got.to_pylist()[0] == want.to_pylist()[0]
    for name in schema.names:
        a, b = got.column(name).to_pylist(), want.column(name).to_pylist()
        assert [repr(v) for v in a] == [repr(v) for v in b], name
    assert rows_table([], schema).num_rows == 0


def test_a_campaigns_tables_are_written_and_read_without_pandas(tmp_path):
    """Writing rows and results and reading them back (what a linear campaign's cases,
    summary and budget lines do) leaves pandas unimported in a fresh process."""
    import subprocess
    import sys

    code = f"""
import sys, numpy as np, pyarrow as pa
from orchestrator.campaign.store import write_table
from orchestrator.results import rows_table, read_parquet
t = rows_table([{{"a": "x", "v": 1.0, "p": None}}], pa.schema([("a", pa.string()),
               ("v", pa.float64()), ("p", pa.bool_())]))
write_table(t, {str(tmp_path / 'r.parquet')!r})
write_table(t, {str(tmp_path / 'r.csv')!r}, csv=True)
assert read_parquet({str(tmp_path / 'r.parquet')!r}).to_pylist() == [{{"a": "x", "v": 1.0, "p": None}}]
print('pandas' in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"
