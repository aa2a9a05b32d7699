"""The master's schedule of a plan as C tables, and the container's model description.

:func:`c_tables` writes ``container_data.h`` for ``csrc/container.c``: the bus slots,
the raw FMI calls of every distinct tick of the hyperperiod (the programs of
:meth:`orchestrator.cosim.schedule.Schedule.layout`, flattened into parts exactly as
:class:`orchestrator.cosim.fastloop.FastLoop` flattens them), the initialisation order
and its reads and writes, the scenario's start values and timed actions, and the
container's variables.  :func:`model_description` writes the matching
``modelDescription.xml``, with ModelStructure dependencies derived from the inner FMUs'
and the wiring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from xml.etree import ElementTree as ET

from orchestrator.cosim.bus import Bus
from orchestrator.cosim.fastloop import flatten_programs
from orchestrator.cosim.graph import init_order

__all__ = ["ContainerVariable", "c_tables", "model_description"]

_TYPE_CODE = {"Real": 0, "Integer": 1, "Enumeration": 1, "Boolean": 2, "String": 3}
_CAUSALITY = {"output": 0, "input": 1, "parameter": 2}
# fastloop.c kinds and container.c functions
READ_REAL, READ_INT, SET_REAL, SET_INT, SET_BOOL, DO_STEP = range(6)
_GET_FN = {"Real": 0, "Integer": 1, "Boolean": 2}
_SET = {"Real": (SET_REAL, 3), "Integer": (SET_INT, 4), "Boolean": (SET_BOOL, 5)}


@dataclass(frozen=True)
class ContainerVariable:
    """One variable of the container: an inner ``instance.variable`` exposed.

    Attributes
    ----------
    name : str
        ``instance.variable``.
    causality : str
        ``output``, ``input`` or ``parameter``.
    instance, variable : str
        The inner instance and its variable.
    """

    name: str
    causality: str
    instance: str
    variable: str


def _c_str(text: str, what: str = "a name") -> str:
    # deferred: nativefmu.build imports fmpy, which the tables do not otherwise need
    from nativefmu.build import c_string

    return c_string(text, what)


def _c_double(x: float) -> str:
    if math.isinf(x):
        return "HUGE_VAL" if x > 0 else "-HUGE_VAL"
    return float(x).hex()


def _array(ctype: str, name: str, values, fmt=str) -> str:
    vals = list(values) or [0]
    body = ", ".join(fmt(v) for v in vals)
    return f"static const {ctype} {name}[{len(vals)}] = {{{body}}};"


def _parts(plan, bus: Bus, layout):
    """Parts, ops and programs as FastLoop builds them, from the bus's layout."""
    parts, part_of, per_inst = [], {}, {}

    def add(**p):
        parts.append(p)
        return len(parts) - 1

    for inst_index, inst in enumerate(plan.scenario.instances):
        name = inst.name
        sets = []
        for t in ("Real", "Integer", "Boolean"):
            items = bus.inputs[name][t]
            if not items:
                continue
            kind, fn = _SET[t]
            gain = [g for _, _, g, _ in items]
            offset = [o for _, _, _, o in items]
            sets.append(add(kind=kind, fn=fn, inst=inst_index, vr=[v.vr for v, *_ in items],
                            idx=[i for _, i, _, _ in items], gain=gain, offset=offset,
                            scaled=int(any(g != 1.0 for g in gain)
                                       or any(o != 0.0 for o in offset)), start=0))

        def reads(region, name=name, inst_index=inst_index):
            out = []
            for t in ("Real", "Integer", "Boolean"):
                off, vs = bus.reads[name][t]
                if vs:
                    out.append(add(kind=READ_REAL if t == "Real" else READ_INT,
                                   fn=_GET_FN[t], inst=inst_index, vr=[v.vr for v in vs],
                                   idx=[], gain=[], offset=[], scaled=0, start=region + off))
            return out
        step = [add(kind=DO_STEP, fn=6, inst=inst_index, vr=[], idx=[], gain=[], offset=[],
                    scaled=0, start=0)]
        read = reads(bus.n)
        pre = reads(2 * bus.n) if name in bus.ft_sources else []
        part_of[("set", name)] = sets + pre
        part_of[("advance", name)] = step + read
        part_of[("step", name)] = sets + step + read
        per_inst[name] = (read, sets)
    programs, prog_of_tick = layout
    ops, prog, snap = flatten_programs(programs, part_of)
    return parts, ops, prog, snap, list(prog_of_tick), per_inst


def _value(inst_index: int, v, value) -> str:
    t = _TYPE_CODE[v.type]
    if v.type == "String":
        return (f"{{{inst_index}, {t}, {v.vr}u, 0.0, "
                f"{_c_str(str(value), f'the String {v.name!r}')}}}")
    x = float(bool(value)) if v.type == "Boolean" else float(value)
    return f"{{{inst_index}, {t}, {v.vr}u, {_c_double(x)}, NULL}}"


def c_tables(plan, bus: Bus, layout, units: dict, variables: list, *, model_identifier: str,
             guid: str, fmi: int = 2) -> str:
    """``container_data.h``: every table ``container.c`` reads.

    Parameters
    ----------
    plan : Plan
        The checked scenario.
    bus : Bus
        ``Bus(plan)``.
    layout : tuple
        ``Schedule.layout()`` of the plan (no algebraic loop).
    units : dict of str to (str, str, str)
        Per instance: the unit's C prefix (``u1``), the inner GUID and the resource
        folder.
    variables : list of ContainerVariable
        The container's variables; the value reference of each is its position.
    model_identifier, guid : str
        The container's (under FMI 3.0 the instantiation token).
    fmi : {2, 3}
        FMI version of the container's API (``CT_FMI_VERSION``).
    """
    sc, tb = plan.scenario, plan.timebase
    names = [i.name for i in sc.instances]
    index = {n: i for i, n in enumerate(names)}
    parts, ops, prog, snap, prog_of_tick, per_inst = _parts(plan, bus, layout)
    prefixes = sorted({u[0] for u in units.values()}, key=lambda p: int(p[1:]))
    fns = ("Instantiate", "FreeInstance", "SetupExperiment", "EnterInitializationMode",
           "ExitInitializationMode", "Terminate", "Reset", "SetDebugLogging", "GetReal",
           "GetInteger", "GetBoolean", "GetString", "SetReal", "SetInteger", "SetBoolean",
           "SetString", "DoStep", "GetFMUstate", "SetFMUstate", "FreeFMUstate",
           "SerializedFMUstateSize", "SerializeFMUstate", "DeSerializeFMUstate")
    t0 = tb.start + 0 * tb.base
    d = t0.denominator * tb.base.denominator
    a = t0.numerator * tb.base.denominator
    b = tb.base.numerator * t0.denominator
    lines = [f"/* Generated by nativefmu.container for {model_identifier} (do not edit). */",
             f"#define CT_MODEL_IDENTIFIER {_c_str(model_identifier)}",
             f"#define CT_GUID {_c_str(guid)}",
             f"#define CT_FMI_VERSION {int(fmi)}",
             f"#define CT_N_INST {len(names)}",
             f"#define CT_N_SLOTS {max(bus.n, 1)}",
             f"#define CT_N_PARTS {max(len(parts), 1)}",
             f"#define CT_N_PARTS_USED {len(parts)}",
             f"#define CT_N_BUF {max(1, sum(len(p['vr']) for p in parts))}",
             f"#define CT_HYPERPERIOD {len(prog_of_tick)}",
             f"#define CT_N_VARS {len(variables)}",
             f"#define CT_TIME_A INT64_C({a})",
             f"#define CT_TIME_B INT64_C({b})",
             f"#define CT_TIME_D INT64_C({d})",
             f"#define CT_MAX_TICK INT64_C({(2**53 - abs(a)) // b})",
             f"#define CT_BASE_STEP {_c_double(float(tb.base))}",
             f"#define CT_START_TIME {_c_double(t0.numerator / t0.denominator)}", ""]
    for p in prefixes:
        lines += [f"extern fmi2{fn}TYPE {p}_fmi2{fn};" for fn in fns]
    lines.append("static const ct_unit CT_UNITS[] = {")
    for p in prefixes:
        lines.append("    {" + ", ".join(f"{p}_fmi2{fn}" for fn in fns) + "},")
    lines.append("};")
    reads, writes, insts = [], [], []
    for name, inst in zip(names, sc.instances):
        prefix, inner_guid, folder = units[name]
        read, sets = per_inst[name]
        r0, w0 = len(reads), len(writes)
        reads += read
        writes += sets
        insts.append(f"    {{{_c_str(name)}, {prefixes.index(prefix)}, {_c_str(inner_guid)}, "
                     f"{_c_str(folder)}, {_c_double(inst.period.numerator / inst.period.denominator)}, "
                     f"{r0}, {len(reads)}, {w0}, {len(writes)}}},")
    lines += ["static const ct_inst CT_INSTS[CT_N_INST] = {", *insts, "};"]
    lines.append(_array("int", "CT_READS", reads))
    lines.append(_array("int", "CT_WRITES", writes))
    order = init_order(names, sc.connections, {n: plan.fmus[n].feedthrough for n in names})
    lines.append(_array("int", "CT_INIT_ORDER", [index[n] for n in order]))
    vr, idx, gain, offset, rows = [], [], [], [], []
    for p in parts:
        off = len(vr)
        nv = len(p["vr"])
        vr += p["vr"]
        idx += p["idx"] or [0] * nv
        gain += p["gain"] or [1.0] * nv
        offset += p["offset"] or [0.0] * nv
        rows.append(f"    {{{p['kind']}, {p['fn']}, {p['inst']}, {nv}, {p['start']}, {off}, "
                    f"{p['scaled']}}},")
    lines += ["static const ct_part CT_PARTS[CT_N_PARTS] = {", *(rows or ["    {0}"]), "};"]
    lines.append(_array("uint32_t", "CT_VR", vr, lambda v: f"{v}u"))
    lines.append(_array("int64_t", "CT_IDX", idx))
    lines.append(_array("double", "CT_GAIN", gain, _c_double))
    lines.append(_array("double", "CT_OFFSET", offset, _c_double))
    lines.append(_array("int64_t", "CT_OPS", ops))
    lines.append(_array("int64_t", "CT_PROG", prog))
    lines.append(_array("int64_t", "CT_SNAP", snap))
    lines.append(_array("int64_t", "CT_PROG_OF_TICK", prog_of_tick))
    lo = list(bus.lo) or [0.0, 0.0]
    hi = list(bus.hi) or [0.0, 0.0]
    lines.append(_array("double", "CT_LO", lo, _c_double))
    lines.append(_array("double", "CT_HI", hi, _c_double))
    slot_names = [""] * max(bus.n, 1)
    slot_inst = [""] * max(bus.n, 1)
    for (inst, var), i in bus.slot.items():
        slot_names[i], slot_inst[i] = var, inst
    lines.append(_array("char *const", "CT_SLOT_NAMES", slot_names, _c_str))
    lines.append(_array("char *const", "CT_SLOT_INST", slot_inst, _c_str))
    starts = [f"    {_value(index[i.name], plan.fmus[i.name].variables[k], v)},"
              for i in sc.instances for k, v in i.parameters.items()]
    lines += [f"#define CT_N_START {len(starts)}",
              "static const ct_value CT_START[] = {", *(starts or ["    {0, 0, 0u, 0.0, NULL}"]),
              "};"]
    actions = []
    for act in sorted(sc.actions, key=lambda x: x.time):   # stable: scenario order per time
        k = tb.ticks_of(act.time)
        per = {}
        for (inst, var), value in act.values.items():
            per.setdefault(inst, []).append((plan.fmus[inst].variables[var], value))
        for inst, vals in per.items():
            actions += [f"    {{INT64_C({k}), {_value(index[inst], v, value)}}},"
                        for v, value in vals]
    lines += [f"#define CT_N_ACTIONS {len(actions)}",
              "static const ct_action CT_ACTIONS[] = {",
              *(actions or ["    {INT64_C(-1), {0, 0, 0u, 0.0, NULL}}"]), "};"]
    rows = []
    for cv in variables:
        v = plan.fmus[cv.instance].variables[cv.variable]
        slot = int(bus.record_idx[list(sc.record).index(cv.name)]) \
            if cv.causality == "output" else -1
        rows.append(f"    {{{_c_str(cv.name)}, {_TYPE_CODE[v.type]}, {_CAUSALITY[cv.causality]}, "
                    f"{index[cv.instance]}, {v.vr}u, {slot}}},")
    lines += ["static const ct_var CT_VARS[] = {", *(rows or ["    {\"\", 0, 0, 0, 0u, -1}"]),
              "};", ""]
    return "\n".join(lines)


def _dependencies(plan, bus: Bus, variables: list):
    """Per output: container inputs it depends on at a step, and inputs and parameters
    at initialisation (1-based indices into ``variables``)."""
    sc = plan.scenario
    pos = {(cv.instance, cv.variable): i + 1 for i, cv in enumerate(variables)}
    source = {(c.target, c.target_var): (c.source, c.source_var, c) for c in sc.connections}
    n = bus.n

    def step_deps(inst, var, seen):
        out = set()
        for u in plan.fmus[inst].feedthrough.get(var, ()):
            if (inst, u) in pos:
                out.add(pos[(inst, u)])
            elif (inst, u) in source:
                src, svar, _ = source[(inst, u)]
                idx = next(i for v, i, _, _ in
                           bus.inputs[inst][plan.fmus[inst].variables[u].type] if v.name == u)
                if idx >= 2 * n and (src, svar) not in seen:   # read at t_k before stepping
                    out |= step_deps(src, svar, seen | {(src, svar)})
        return out

    def initial(inst):
        md = plan.fmus[inst].model_description
        table = {}
        for unk in md.initialUnknowns:
            deps = unk.dependencies
            table[unk.variable.name] = None if deps is None else [d.name for d in deps]
        return table

    init_tables = {}

    def init_deps(inst, var, seen):
        if inst not in init_tables:
            init_tables[inst] = initial(inst)
        deps = init_tables[inst].get(var)
        if deps is None:   # not listed or "depends on all": every input and parameter
            deps = [k for k, v in plan.fmus[inst].variables.items()
                    if v.causality in ("input", "parameter")]
        out = set()
        for d in deps:
            if (inst, d) in pos:
                out.add(pos[(inst, d)])
            elif (inst, d) in source:
                src, svar, _ = source[(inst, d)]
                if (src, svar) not in seen:
                    out |= init_deps(src, svar, seen | {(src, svar)})
        return out

    result = {}
    for i, cv in enumerate(variables):
        if cv.causality != "output":
            continue
        key = (cv.instance, cv.variable)
        rec = int(bus.record_idx[list(sc.record).index(cv.name)])
        step = step_deps(*key, {key}) if rec >= 2 * n else set()
        inputs = {j for j in step if variables[j - 1].causality == "input"}
        init = {j for j in init_deps(*key, {key})
                if variables[j - 1].causality in ("input", "parameter")}
        result[i + 1] = (sorted(inputs), sorted(init | inputs))
    return result


def model_description(plan, bus: Bus, variables: list, *, model_identifier: str, guid: str,
                      source_files: list, description: str) -> bytes:
    """``modelDescription.xml`` of the container.

    Parameters
    ----------
    plan : Plan
    bus : Bus
    variables : list of ContainerVariable
        In value-reference order.
    model_identifier, guid : str
    source_files : list of str
        The ``.c`` files of ``sources/`` to compile.
    description : str
        One line for the ``description`` attribute.
    """
    sc, tb = plan.scenario, plan.timebase
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": model_identifier, "guid": guid,
        "description": description, "generationTool": "jitterfmu nativefmu container 1",
        "variableNamingConvention": "flat", "numberOfEventIndicators": "0"})
    cs = ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": model_identifier, "needsExecutionTool": "false",
        "canHandleVariableCommunicationStepSize": "true",
        "canInterpolateInputs": "false", "maxOutputDerivativeOrder": "0",
        "canRunAsynchronuously": "false", "canBeInstantiatedOnlyOncePerProcess": "false",
        "canNotUseMemoryManagementFunctions": "true", "canGetAndSetFMUstate": "true",
        "canSerializeFMUstate": "true", "providesDirectionalDerivative": "false"})
    files = ET.SubElement(cs, "SourceFiles")
    for name in source_files:
        ET.SubElement(files, "File", {"name": name})
    units = {}
    for cv in variables:
        md = plan.fmus[cv.instance].model_description
        for u in md.unitDefinitions:
            units.setdefault(u.name, u)
    used = {plan.fmus[cv.instance].variables[cv.variable].unit for cv in variables}
    ud = ET.SubElement(root, "UnitDefinitions")
    for name in sorted(u for u in used if u):
        u = units.get(name)
        el = ET.SubElement(ud, "Unit", {"name": name})
        bu = ET.SubElement(el, "BaseUnit")
        if u is not None and u.baseUnit is not None:
            for attr in ("kg", "m", "s", "A", "K", "mol", "cd", "rad", "factor", "offset"):
                val = getattr(u.baseUnit, attr, None)
                if val not in (None, 0, 0.0) and not (attr == "factor" and val == 1.0):
                    bu.set(attr, repr(val) if isinstance(val, float) else str(val))
        for du in (u.displayUnits if u is not None else []):
            attrs = {"name": du.name}
            if du.factor != 1.0:
                attrs["factor"] = repr(du.factor)
            if du.offset != 0.0:
                attrs["offset"] = repr(du.offset)
            ET.SubElement(el, "DisplayUnit", attrs)
    if not len(ud):
        root.remove(ud)
    ET.SubElement(root, "DefaultExperiment", {
        "startTime": repr(float(tb.start)), "stopTime": repr(float(sc.experiment.stop)),
        "stepSize": repr(float(tb.base))})
    mv = ET.SubElement(root, "ModelVariables")
    starts = {}
    for inst in sc.instances:
        for k, value in inst.parameters.items():
            starts[(inst.name, k)] = value
    for vr, cv in enumerate(variables):
        v = plan.fmus[cv.instance].variables[cv.variable]
        inner = next(x for x in plan.fmus[cv.instance].model_description.modelVariables
                     if x.name == cv.variable)
        variability = v.variability
        if cv.causality == "output" and v.type != "Real" and variability == "continuous":
            variability = "discrete"
        text = inner.description or ""
        sv = ET.SubElement(mv, "ScalarVariable", {
            "name": cv.name, "valueReference": str(vr),
            "description": f"{cv.instance}: {text}" if text else f"{cv.instance}.{cv.variable}",
            "causality": cv.causality, "variability": variability})
        t = "Integer" if v.type == "Enumeration" else v.type
        el = ET.SubElement(sv, t)
        if t == "Real":
            if v.unit:
                el.set("unit", v.unit)
            du = getattr(inner, "displayUnit", None)
            if du:
                el.set("displayUnit", du)
            if math.isfinite(v.min):
                el.set("min", repr(v.min))
            if math.isfinite(v.max):
                el.set("max", repr(v.max))
        if cv.causality != "output":
            value = starts.get((cv.instance, cv.variable), v.start)
            if t == "Boolean":
                value = "true" if value in (True, "true", "1", 1) else "false"
            elif t == "Real":
                value = repr(float(value))
            elif t == "Integer":
                value = str(int(value))
            el.set("start", str(value))
    ms = ET.SubElement(root, "ModelStructure")
    deps = _dependencies(plan, bus, variables)
    outs = ET.SubElement(ms, "Outputs")
    init = ET.SubElement(ms, "InitialUnknowns")
    for index in sorted(deps):
        step, at_init = deps[index]
        ET.SubElement(outs, "Unknown", {"index": str(index),
                                        "dependencies": " ".join(map(str, step)),
                                        "dependenciesKind": " ".join(["dependent"] * len(step))})
        ET.SubElement(init, "Unknown", {"index": str(index),
                                        "dependencies": " ".join(map(str, at_init)),
                                        "dependenciesKind": " ".join(["dependent"] *
                                                                     len(at_init))})
    if not len(init):
        ms.remove(init)
    if not len(outs):
        ms.remove(outs)
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
