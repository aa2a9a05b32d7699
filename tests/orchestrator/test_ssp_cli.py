"""SSP export/import, libcosim agreement and the run / export-ssp commands."""

import json

import numpy as np
import pytest
import tomli_w

from orchestrator import load_scenario, prepare, run_scenario
from orchestrator.cli import main
from orchestrator.results import read_table
from orchestrator.scenario import JacobiExportWarning, ScenarioError, read_ssp, write_ssp

pytestmark = [pytest.mark.slow,
              pytest.mark.filterwarnings("ignore::orchestrator.cosim.UnconnectedInputWarning")]


def mixed(algorithm="jacobi", stop=0.2):
    """Five instances at 1, 2 and 4 ms with gains, offsets and a feedback loop."""
    return {
        "experiment": {"stop": stop, "output_interval": 1e-3, "algorithm": algorithm},
        "fmus": {
            "ramp": {"fmu": "MtIntegrator", "period": 1e-3, "parameters": {"u": 1.0}},
            # x0 = 0: libcosim propagates outputs as they were before
            # fmi2ExitInitializationMode, the master after it (dependency order), so the
            # two agree from the first step only when initial outputs equal start values
            "plant": {"fmu": "MtIntegrator", "period": 1e-3, "parameters": {"x0": 0.0}},
            "ctrl": {"fmu": "MtGain", "period": 4e-3, "parameters": {"k": -5.0, "b": 1.0}},
            "g2": {"fmu": "MtGain", "period": 2e-3, "parameters": {"k": 3.0}},
            "sink": {"fmu": "MtIntegrator", "period": 4e-3, "parameters": {"k": 2.0}},
        },
        "connections": [
            {"from": "plant.x", "to": "ctrl.u", "gain": 0.5, "offset": 0.1},
            {"from": "ctrl.y", "to": "plant.u"},
            {"from": "ramp.x", "to": "g2.u"},
            {"from": "g2.y", "to": "sink.u", "gain": -1.0},
        ],
        "record": {"variables": ["plant.x", "ctrl.y", "ramp.x", "g2.y", "sink.x"]},
    }


PERIOD_TICKS = {"plant": 1, "ctrl": 4, "ramp": 1, "g2": 2, "sink": 4}


def run_libcosim(ssp, record, n_steps):
    """Run an SSP archive in libcosim, reading outputs after every base step."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    ex = CosimExecution.from_ssp_file(str(ssp))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    idx, vrs = {}, {}
    for ref in record:
        inst, var = ref.split(".")
        i = ex.slave_index_from_instance_name(inst)
        vr = next(v.reference for v in ex.slave_variables(i) if v.name.decode() == var)
        idx[ref], vrs[ref] = i, vr
    rows = np.empty((n_steps, len(record)))
    for k in range(n_steps):
        assert ex.step(1)
        rows[k] = [obs.last_real_values(idx[r], [vrs[r]])[0] for r in record]
    return rows


def test_ssp_round_trip_restores_the_scenario(fmu_dir, tmp_path):
    ssp = write_ssp(prepare(load_scenario(mixed()), fmu_dir), tmp_path / "mixed.ssp")
    sc = read_ssp(ssp)
    assert [i.name for i in sc.instances] == list(mixed()["fmus"])
    assert {i.name: float(i.period) for i in sc.instances} == {
        "ramp": 1e-3, "plant": 1e-3, "ctrl": 4e-3, "g2": 2e-3, "sink": 4e-3}
    assert sc.instance("ctrl").parameters == {"k": -5.0, "b": 1.0}
    assert sc.instance("plant").parameters == {"x0": 0.0}
    assert [(c.start, c.end, c.gain, c.offset) for c in sc.connections][0] == (
        "plant.x", "ctrl.u", 0.5, 0.1)
    assert sc.record == tuple(mixed()["record"]["variables"])
    import zipfile
    ssd = zipfile.ZipFile(ssp).read("SystemStructure.ssd").decode()
    assert '<osp:FixedStepAlgorithm baseStepSize="0.001"' in ssd
    assert '<osp:StepSizeHint value="0.004"' in ssd
    assert '<ssc:LinearTransformation factor="0.5" offset="0.1"' in ssd


def test_libcosim_runs_the_exported_ssp_like_jacobi(fmu_dir, tmp_path):
    ssp = write_ssp(prepare(load_scenario(mixed()), fmu_dir), tmp_path / "mixed.ssp")
    ours = run_scenario(ssp)          # the archive itself, parsed back
    record = list(ours.table)[1:]
    theirs = run_libcosim(ssp, record, n_steps=len(ours.time) - 1)
    # compare each variable at its own instance's communication points, where both
    # masters show the output of the step that just ended
    for j, ref in enumerate(record):
        p = PERIOD_TICKS[ref.split(".")[0]]
        rows = np.arange(p, len(ours.time), p)
        np.testing.assert_allclose(ours[ref][rows], theirs[rows - 1, j], rtol=0, atol=1e-9,
                                   err_msg=ref)
    assert np.ptp(ours["plant.x"]) > 0.01  # the loop actually moved


def test_export_of_a_gauss_seidel_scenario_warns_about_jacobi_masters(fmu_dir, tmp_path,
                                                                      recwarn):
    # MtGain's y depends on its u (y = k u + b): ctrl.y drives plant.u and g2.y drives
    # sink.u; Gauss-Seidel reads them after the gains' inputs are set, a Jacobi master one
    # step late
    with pytest.warns(JacobiExportWarning, match=r"2 direct-feedthrough connection\(s\) "
                                                 r"\(ctrl\.y -> plant\.u, g2\.y -> sink\.u\)"):
        ssp = write_ssp(prepare(load_scenario(mixed("gauss-seidel")), fmu_dir),
                        tmp_path / "gs.ssp")
    assert read_ssp(ssp).experiment.algorithm == "gauss-seidel"   # recorded in the archive
    # the same scenario stepped Jacobi, or one without feedthrough, exports silently
    write_ssp(prepare(load_scenario(mixed("jacobi")), fmu_dir), tmp_path / "j.ssp")
    no_ft = mixed("gauss-seidel")
    no_ft["connections"] = [c for c in no_ft["connections"]
                            if c["from"] not in ("ctrl.y", "g2.y")]
    write_ssp(prepare(load_scenario(no_ft), fmu_dir), tmp_path / "noft.ssp")
    assert not [w for w in recwarn if issubclass(w.category, JacobiExportWarning)]


def test_run_command_writes_results_and_metadata(fmu_dir, tmp_path, capsys):
    scen = tmp_path / "mixed.toml"
    scen.write_text(tomli_w.dumps(mixed("gauss-seidel", stop=0.02)))
    out = tmp_path / "out"
    code = main(["run", str(scen), "--out", str(out), "--fmu-dir", str(fmu_dir),
                 "--set", "ctrl.k=-2.5", "--stop-time", "0.01", "--csv", "--quiet"])
    assert code == 0
    table = read_table(out / "results.csv")
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "ok" and meta["stop"] == 0.01 and meta["rows"] == 11
    assert len(meta["scenario_sha256"]) == 64
    assert set(meta["fmus"]["ctrl"]) == {"fmu", "sha256", "period"}
    assert meta["versions"]["fmpy"] == "0.3.32"
    ref = run_scenario(scen, stop_time=0.01, overrides={"ctrl.k": -2.5}, fmu_dir=fmu_dir)
    np.testing.assert_array_equal(table["ctrl.y"], ref["ctrl.y"])
    assert "11 rows x 5 variables" in capsys.readouterr().out


def test_run_command_exit_status_on_failure(fmu_dir, tmp_path, capsys):
    d = mixed(stop=0.02)
    d["fmus"]["bad"] = {"fmu": "MtFaulty", "period": 1e-3,
                        "parameters": {"fail_time": 0.005, "mode": 1}}
    scen = tmp_path / "bad.toml"
    scen.write_text(tomli_w.dumps(d))
    code = main(["run", str(scen), "--out", str(tmp_path / "o"), "--fmu-dir", str(fmu_dir)])
    err = capsys.readouterr().err
    assert code == 1
    assert "instance 'bad' failed in fmi2DoStep at t = 0.005 s" in err
    assert "6 rows recorded so far" in err
    assert len(read_table(tmp_path / "o" / "results.parquet")["time"]) == 6


def test_export_command_and_malformed_ssp(fmu_dir, tmp_path, capsys):
    scen = tmp_path / "mixed.toml"
    scen.write_text(tomli_w.dumps(mixed()))
    assert main(["export-ssp", str(scen), str(tmp_path / "m.ssp"),
                 "--fmu-dir", str(fmu_dir)]) == 0
    assert (tmp_path / "m.ssp").is_file()
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "SystemStructure.ssd").write_text("<?xml version='1.0'?>\n<a>\n<b></a>\n")
    with pytest.raises(ScenarioError, match="not well-formed XML at line 3"):
        read_ssp(bad)
    assert main(["run", str(tmp_path / "missing.toml")]) == 2
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.parametrize("attr, value, named", [
    ("stopTime", "abc", "DefaultExperiment stopTime is 'abc', not a number"),
    ("startTime", "x1", "DefaultExperiment startTime is 'x1', not a number"),
    ("baseStepSize", "fast", "baseStepSize is 'fast', not a number"),
])
def test_ssp_with_a_non_numeric_attribute_names_file_and_attribute(fmu_dir, tmp_path, attr,
                                                                   value, named):
    import re
    import zipfile

    ssp = write_ssp(prepare(load_scenario(mixed()), fmu_dir), tmp_path / "mixed.ssp")
    bad = tmp_path / "bad.ssp"
    with zipfile.ZipFile(ssp) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "SystemStructure.ssd":
                data = re.sub(rf'{attr}="[^"]*"'.encode(), f'{attr}="{value}"'.encode(), data,
                              count=1)
            zout.writestr(item, data)
    with pytest.raises(ScenarioError, match=re.escape("bad.ssp/SystemStructure.ssd: ") + ".*"
                       + re.escape(named)):
        read_ssp(bad)


from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402


@pytest.fixture(scope="module")
def ssp_file(fmu_dir, tmp_path_factory):
    return write_ssp(prepare(load_scenario(mixed()), fmu_dir),
                     tmp_path_factory.mktemp("ssp") / "m.ssp")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_a_damaged_ssp_archive_is_read_or_refused_in_one_sentence(ssp_file, data):
    import io
    import tempfile
    import zipfile
    from pathlib import Path

    ssp_bytes = ssp_file.read_bytes()
    how = data.draw(st.sampled_from(["truncate", "flip", "ssd"]))
    blob = bytearray(ssp_bytes)
    if how == "truncate":
        blob = blob[:data.draw(st.integers(0, len(blob) - 1))]
    elif how == "flip":
        for _ in range(data.draw(st.integers(1, 8))):
            i = data.draw(st.integers(0, len(blob) - 1))
            blob[i] ^= data.draw(st.integers(1, 255))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "damaged.ssp"
        if how == "ssd":   # a valid archive whose SystemStructure.ssd is mangled text
            text = zipfile.ZipFile(io.BytesIO(ssp_bytes)).read(
                "SystemStructure.ssd").decode()
            cut = data.draw(st.integers(0, len(text)))
            junk = data.draw(st.text(max_size=20))
            with zipfile.ZipFile(io.BytesIO(ssp_bytes)) as zin, \
                    zipfile.ZipFile(path, "w") as zout:
                for item in zin.infolist():
                    body = zin.read(item.filename)
                    if item.filename == "SystemStructure.ssd":
                        body = (text[:cut] + junk + text[cut + len(junk):]).encode()
                    zout.writestr(item.filename, body)
        else:
            path.write_bytes(bytes(blob))
        try:
            read_ssp(path)
        except ScenarioError as exc:
            assert "\n" not in str(exc).strip()


def test_written_archive_follows_the_ssp_schemas_and_reads_in_fmpy(fmu_dir, tmp_path):
    """The archive is checked against the SSP 1.0 schemas fmpy ships, and fmpy's own SSD
    reader (an independent implementation) finds the same components and connections."""
    import zipfile

    from fmpy.ssp.ssd import read_ssd, validate_tree
    from lxml import etree

    ssp = write_ssp(prepare(load_scenario(mixed()), fmu_dir), tmp_path / "mixed.ssp")
    with zipfile.ZipFile(ssp) as z:
        validate_tree(etree.fromstring(z.read("SystemStructure.ssd")),
                      "SystemStructureDescription.xsd")
        ssvs = [n for n in z.namelist() if n.endswith(".ssv")]
        assert ssvs
        for name in ssvs:
            validate_tree(etree.fromstring(z.read(name)), "SystemStructureParameterValues.xsd")
    ssd = read_ssd(str(ssp), validate=True)
    comps = {c.name for c in ssd.system.elements}
    assert comps == set(mixed()["fmus"])
    conns = {(f"{c.startElement}.{c.startConnector}", f"{c.endElement}.{c.endConnector}")
             for c in ssd.system.connections}
    assert conns == {(c["from"], c["to"]) for c in mixed()["connections"]}
    mine = read_ssp(ssp)
    assert {i.name for i in mine.instances} == comps


def test_a_member_name_that_is_not_its_utf8_is_one_sentence(ssp_file, tmp_path):
    """A local header that flags its name as UTF-8 and holds other bytes (the damage a
    random byte flip at offset 30 made: zipfile raised UnicodeDecodeError)."""
    blob = bytearray(ssp_file.read_bytes())
    assert blob[:4] == b"PK\x03\x04"
    blob[7] |= 0x08                # general-purpose flag bit 11 (0x800): a UTF-8 name
    blob[30] = 0xD3                # a lead byte without its continuation
    blob[31] = 0x41
    bad = tmp_path / "badname.ssp"
    bad.write_bytes(bytes(blob))
    with pytest.raises(ScenarioError) as exc:
        read_ssp(bad)
    assert "\n" not in str(exc.value).strip()


def test_an_ssd_declaring_an_unknown_encoding_is_one_sentence(ssp_file, tmp_path):
    import zipfile

    bad = tmp_path / "enc.ssp"
    with zipfile.ZipFile(ssp_file) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            body = zin.read(item.filename)
            if item.filename == "SystemStructure.ssd":
                body = body.replace(b"encoding='utf-8'", b"encoding='u0f-8'", 1)
                assert b"u0f-8" in body
            zout.writestr(item.filename, body)
    with pytest.raises(ScenarioError, match="declares an encoding Python does not know"):
        read_ssp(bad)
