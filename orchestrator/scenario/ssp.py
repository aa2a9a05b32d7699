"""SSP 1.0 archives: export a scenario for other tools, and read one back.

The archive holds ``SystemStructure.ssd`` (components, connectors, connections with
linear transformations), the FMUs under ``resources/``, and one ``.ssv`` parameter set
per component.  Per-instance rates are written as OSP annotations so that libcosim
honours them: ``osp:FixedStepAlgorithm baseStepSize`` (the exact base step) in the
default experiment and ``osp:StepSizeHint`` per component.  Output interval,
recorded variables, actions and algorithm ride along in an ``org.jitterfmu`` annotation
that other tools ignore.
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
import zipfile
from fractions import Fraction
from pathlib import Path

from fmutools.archive import ArchiveError, inside
from fmutools.fmucache import CacheError, extract_cached

from ..files import atomic_write
from ..timebase import make_timebase, to_fraction
from .model import Scenario, ScenarioError
from .toml import read_scenario_bytes, scenario_from_dict

__all__ = ["JacobiExportWarning", "read_ssp", "write_ssp"]

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "https://opensimulationplatform.com/SSP/OSPAnnotations",
    "jf": "https://jitterfmu.org/SSP/ScenarioAnnotations",
}
OSP_TYPE = "com.opensimulationplatform"
JF_TYPE = "org.jitterfmu"
_SSV_TYPES = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer",
              "Boolean": "Boolean", "String": "String"}

for _p, _u in NS.items():
    ET.register_namespace(_p, _u)


def _q(tag: str) -> str:
    prefix, name = tag.split(":")
    return f"{{{NS[prefix]}}}{name}"


def _num(x) -> str:
    return repr(float(x))


def _value_text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _whole_ns(x: Fraction, what: str) -> None:
    if (x * 10**9).denominator != 1:
        raise ScenarioError(f"{what} {float(x)!r} s is not a whole number of nanoseconds, "
                            "which libcosim needs; choose periods on a 1 ns grid")


class JacobiExportWarning(UserWarning):
    """An exported Gauss-Seidel scenario computes something else under a Jacobi master."""


def write_ssp(plan, out_path) -> Path:
    """Export a prepared scenario as an SSP 1.0 archive (libcosim-compatible).

    Parameters
    ----------
    plan : orchestrator.cosim.Plan
        The scenario checked against its FMUs (:func:`orchestrator.cosim.prepare`):
        the archive carries those FMU files, and its rates come from the plan's
        timebase.
    out_path : path-like
        The ``.ssp`` file to write (atomically).

    Returns
    -------
    Path
    """
    sc = plan.scenario
    if sc.experiment.algorithm == "gauss-seidel" and plan.feedthrough_edges:
        edges = [f"{c.start} -> {c.end}" for c in plan.feedthrough_edges]
        shown = ", ".join(edges[:3]) + (f" and {len(edges) - 3} more" if len(edges) > 3 else "")
        warnings.warn(JacobiExportWarning(
            f"scenario {Path(sc.source).name or 'scenario'!r} steps Gauss-Seidel and has "
            f"{len(edges)} direct-feedthrough connection(s) ({shown}); a Jacobi master such "
            "as libcosim's fixed-step algorithm reads them one communication step late, so "
            "it computes something else from this archive ('jitterfmu run' on it follows "
            "the algorithm recorded in its org.jitterfmu annotation)"), stacklevel=2)
    tb = plan.timebase
    _whole_ns(tb.base, "base step")
    # one copy of each distinct FMU file under resources/
    fmu_names, used = {}, set()
    for inst in sc.instances:
        path = plan.fmus[inst.name].path
        if path in fmu_names:
            continue
        name = path.name
        i = 1
        while name in used:
            name = f"{path.stem}_{i}{path.suffix}"
            i += 1
        used.add(name)
        fmu_names[path] = name

    root = ET.Element(_q("ssd:SystemStructureDescription"),
                      {"name": Path(sc.source).stem or "system", "version": "1.0"})
    system = ET.SubElement(root, _q("ssd:System"), {"name": Path(sc.source).stem or "system"})
    elements = ET.SubElement(system, _q("ssd:Elements"))
    ssv_files = {}
    for inst in sc.instances:
        info = plan.fmus[inst.name]
        comp = ET.SubElement(elements, _q("ssd:Component"), {
            "name": inst.name, "source": f"resources/{fmu_names[info.path]}",
            "type": "application/x-fmu-sharedlibrary"})
        conns = ET.SubElement(comp, _q("ssd:Connectors"))
        for v in info.variables.values():
            if v.causality not in ("input", "output") or v.type not in _SSV_TYPES:
                continue
            c = ET.SubElement(conns, _q("ssd:Connector"), {"name": v.name, "kind": v.causality})
            attrs = {"unit": v.unit} if (v.unit and v.type == "Real") else {}
            ET.SubElement(c, _q(f"ssc:{_SSV_TYPES[v.type]}"), attrs)
        if inst.parameters:
            ssv_name = f"resources/{inst.name}.ssv"
            pset = ET.Element(_q("ssv:ParameterSet"), {"version": "1.0", "name": inst.name})
            params = ET.SubElement(pset, _q("ssv:Parameters"))
            for pname, value in inst.parameters.items():
                v = info.variables[pname]
                p = ET.SubElement(params, _q("ssv:Parameter"), {"name": pname})
                ET.SubElement(p, _q(f"ssv:{_SSV_TYPES[v.type]}"), {"value": _value_text(value)})
            ssv_files[ssv_name] = pset
            binds = ET.SubElement(comp, _q("ssd:ParameterBindings"))
            ET.SubElement(binds, _q("ssd:ParameterBinding"), {"source": ssv_name})
        _whole_ns(inst.period, f"period of instance {inst.name!r}")
        ann = ET.SubElement(ET.SubElement(comp, _q("ssd:Annotations")), _q("ssc:Annotation"),
                            {"type": OSP_TYPE})
        ET.SubElement(ann, _q("osp:StepSizeHint"), {"value": _num(inst.period)})
    connections = ET.SubElement(system, _q("ssd:Connections"))
    for c in sc.connections:
        el = ET.SubElement(connections, _q("ssd:Connection"), {
            "startElement": c.source, "startConnector": c.source_var,
            "endElement": c.target, "endConnector": c.target_var})
        if c.gain != 1.0 or c.offset != 0.0:
            ET.SubElement(el, _q("ssc:LinearTransformation"),
                          {"factor": repr(c.gain), "offset": repr(c.offset)})
    exp = sc.experiment
    de = ET.SubElement(root, _q("ssd:DefaultExperiment"),
                       {"startTime": _num(exp.start), "stopTime": _num(exp.stop)})
    anns = ET.SubElement(de, _q("ssd:Annotations"))
    osp = ET.SubElement(anns, _q("ssc:Annotation"), {"type": OSP_TYPE})
    ET.SubElement(ET.SubElement(osp, _q("osp:Algorithm")), _q("osp:FixedStepAlgorithm"),
                  {"baseStepSize": _num(tb.base)})
    jf = ET.SubElement(anns, _q("ssc:Annotation"), {"type": JF_TYPE})
    js = ET.SubElement(jf, _q("jf:Scenario"), {
        "outputInterval": str(exp.output_interval), "algorithm": exp.algorithm})
    for inst in sc.instances:
        ET.SubElement(js, _q("jf:Period"), {"element": inst.name, "value": str(inst.period)})
    for ref in sc.record:
        ET.SubElement(js, _q("jf:Record"), {"variable": ref})
    for a in sc.actions:
        act = ET.SubElement(js, _q("jf:Action"), {"time": str(a.time)})
        for (i, var), value in a.values.items():
            t = _SSV_TYPES[plan.fmus[i].variables[var].type]
            ET.SubElement(act, _q("jf:Set"), {"variable": f"{i}.{var}", "type": t,
                                              "value": _value_text(value)})

    out_path = Path(out_path)
    def write(tmp):
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("SystemStructure.ssd", _xml_bytes(root))
            for name, pset in ssv_files.items():
                z.writestr(name, _xml_bytes(pset))
            for path, name in fmu_names.items():
                z.write(path, f"resources/{name}")

    atomic_write(out_path, write)
    return out_path


def _xml_bytes(root) -> bytes:
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def _parse(data: bytes, where: str):
    try:
        return ET.fromstring(data)
    except ET.ParseError as exc:
        line, col = exc.position
        raise ScenarioError(f"{where} is not well-formed XML at line {line}, column {col}: "
                            f"{exc.msg if hasattr(exc, 'msg') else exc}") from None
    except LookupError as exc:   # the XML declaration names an encoding that does not exist
        raise ScenarioError(f"{where} declares an encoding Python does not know ({exc}); "
                            "write it as UTF-8") from None


def _typed(el, where: str):
    """Value of an ssv:Real/Integer/Boolean/String child element."""
    for t, conv in (("Real", float), ("Integer", int),
                    ("Boolean", lambda s: s.strip().lower() in ("true", "1")),
                    ("String", str)):
        child = el.find(f"ssv:{t}", NS)
        if child is None:
            child = el.find(f"jf:{t}", NS)
        if child is not None:
            try:
                return conv(child.get("value"))
            except (TypeError, ValueError):
                raise ScenarioError(f"{where}: {t} value {child.get('value')!r} is not valid")
    raise ScenarioError(f"{where} has no Real, Integer, Boolean or String value")


def _number(text, what: str) -> float:
    """``float(text)``, or one sentence naming the attribute and the archive."""
    try:
        return float(text)
    except (TypeError, ValueError):
        raise ScenarioError(f"{what} is {text!r}, not a number") from None


def _convert(text: str, t: str, where: str):
    try:
        if t == "Real":
            return float(text)
        if t == "Integer":
            return int(text)
        if t == "Boolean":
            return text.strip().lower() in ("true", "1")
        return text
    except ValueError:
        raise ScenarioError(f"{where}: {t} value {text!r} is not valid") from None


def _extract(path: Path) -> Path:
    """Unpack an archive once per content hash into the private extraction cache."""
    try:
        return extract_cached(path, kind="ssp", required="SystemStructure.ssd")
    except CacheError as exc:
        raise ScenarioError(str(exc)) from None


def _inside(folder: Path, ref: str, what: str) -> Path:
    """The file ``ref`` names inside the archive's ``folder``, or one ScenarioError."""
    try:
        return inside(folder, ref, what)
    except ArchiveError as exc:
        raise ScenarioError(str(exc)) from None


def read_ssp(path) -> Scenario:
    """Read an SSP archive (or an extracted folder) back into a Scenario.

    Rates come from ``osp:StepSizeHint`` (else the base step), parameters from each
    component's parameter bindings, and output interval, recording, actions and
    algorithm from the ``org.jitterfmu`` annotation when present (else: output every
    base step, record every connected output, Gauss–Seidel).

    Parameters
    ----------
    path : path-like
        ``.ssp`` archive or folder holding ``SystemStructure.ssd``.

    Returns
    -------
    Scenario
    """
    path = Path(path)
    if not path.exists():
        raise ScenarioError(f"SSP file {str(path)!r} does not exist")
    folder = path if path.is_dir() else _extract(path)
    ssd_path = folder / "SystemStructure.ssd"
    where = f"{path.name}/SystemStructure.ssd"
    root = _parse(read_scenario_bytes(ssd_path, where), where)
    if root.tag != _q("ssd:SystemStructureDescription"):
        raise ScenarioError(f"{where} is not an SSP 1.0 SystemStructureDescription")
    system = root.find("ssd:System", NS)
    if system is None:
        raise ScenarioError(f"{where} has no ssd:System")
    de = root.find("ssd:DefaultExperiment", NS)
    base = None
    jf = None
    if de is not None:
        for ann in de.findall("ssd:Annotations/*", NS):
            if ann.get("type") == OSP_TYPE:
                fsa = ann.find("osp:Algorithm/osp:FixedStepAlgorithm", NS)
                if fsa is not None:
                    base = to_fraction(_number(fsa.get("baseStepSize"), f"{where}: osp:FixedStepAlgorithm baseStepSize"), "baseStepSize")
            elif ann.get("type") == JF_TYPE:
                jf = ann.find("jf:Scenario", NS)
    exact_period = {}
    if jf is not None:
        for p in jf.findall("jf:Period", NS):
            exact_period[p.get("element")] = p.get("value")
    fmus, outputs = {}, []
    for comp in system.findall("ssd:Elements/ssd:Component", NS):
        name, source = comp.get("name"), comp.get("source")
        if not name or not source:
            raise ScenarioError(f"{where}: a Component lacks 'name' or 'source'")
        if name in fmus:
            raise ScenarioError(f"{where} has two components named {name!r}; give each "
                                "component its own name")
        fmu_path = _inside(folder, source, f"{where}: source of component {name!r}").resolve()
        spec = {"fmu": str(fmu_path)}
        hint = None
        for ann in comp.findall("ssd:Annotations/*", NS):
            if ann.get("type") == OSP_TYPE and ann.find("osp:StepSizeHint", NS) is not None:
                hint = ann.find("osp:StepSizeHint", NS).get("value")
        if name in exact_period:
            spec["period"] = exact_period[name]
        elif hint is not None:
            spec["period"] = _number(hint, f"{where}: osp:StepSizeHint of component {name!r}")
        elif base is not None:
            spec["period"] = base
        else:
            raise ScenarioError(f"{where}: component {name!r} has no osp:StepSizeHint and the "
                                "system no osp:FixedStepAlgorithm baseStepSize")
        params = {}
        for binding in comp.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            if binding.get("source"):
                ssv = _inside(folder, binding.get("source"),
                              f"{where}: parameter binding source of component {name!r}")
                if not ssv.is_file():
                    raise ScenarioError(f"{where}: parameter file {binding.get('source')!r} "
                                        f"of component {name!r} is missing")
                ssv_name = f"{path.name}/{binding.get('source')}"
                pset = _parse(read_scenario_bytes(ssv, ssv_name), ssv_name)
            else:
                pset = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
                if pset is None:
                    continue
            for p in pset.findall("ssv:Parameters/ssv:Parameter", NS):
                params[p.get("name")] = _typed(p, f"parameter {name}.{p.get('name')}")
        if params:
            spec["parameters"] = params
        fmus[name] = spec
        for c in comp.findall("ssd:Connectors/ssd:Connector", NS):
            if c.get("kind") == "output":
                outputs.append(f"{name}.{c.get('name')}")
    connections = []
    for c in system.findall("ssd:Connections/ssd:Connection", NS):
        item = {"from": f"{c.get('startElement')}.{c.get('startConnector')}",
                "to": f"{c.get('endElement')}.{c.get('endConnector')}"}
        lt = c.find("ssc:LinearTransformation", NS)
        if lt is not None:
            item["gain"] = _number(lt.get("factor", "1"), f"{where}: LinearTransformation factor of {item['to']}")
            item["offset"] = _number(lt.get("offset", "0"), f"{where}: LinearTransformation offset of {item['to']}")
        connections.append(item)
    if de is None or de.get("stopTime") is None:
        raise ScenarioError(f"{where} has no DefaultExperiment stopTime")
    experiment = {"start": _number(de.get("startTime", "0"), f"{where}: DefaultExperiment startTime"),
                  "stop": _number(de.get("stopTime"), f"{where}: DefaultExperiment stopTime")}
    data = {"experiment": experiment, "fmus": fmus, "connections": connections}
    if jf is not None:
        experiment["output_interval"] = jf.get("outputInterval")
        experiment["algorithm"] = jf.get("algorithm", "gauss-seidel")
        data["record"] = {"variables": [r.get("variable") for r in jf.findall("jf:Record", NS)]}
        actions = []
        for a in jf.findall("jf:Action", NS):
            values = {s.get("variable"): _convert(s.get("value"), s.get("type"),
                                                  f"action at {a.get('time')} s")
                      for s in a.findall("jf:Set", NS)}
            actions.append({"time": a.get("time"), "set": values})
        data["actions"] = actions
    else:
        if base is None:
            tb = make_timebase({n: s["period"] for n, s in fmus.items()}, 1, 1)
            base = tb.base
        experiment["output_interval"] = base
        used = {c["from"] for c in connections}
        data["record"] = {"variables": [o for o in outputs if o in used]}
    try:
        return scenario_from_dict(data, folder, str(path))
    except ScenarioError as exc:
        raise ScenarioError(f"{path}: {exc}") from None
