"""Complete pythonfmu's modelDescription.xml: units, ModelStructure, capability flags.

pythonfmu writes variables without units and a ModelStructure whose outputs carry no
``dependencies``, so every output looks like direct feedthrough of every input and
``InitialUnknowns`` is missing.  :func:`complete_model_description` fixes both from
the :class:`fmukit.slave.VariableSpec` list of a slave.  :func:`check_model_description`
holds the project's own checks on a finished FMU (used by ``jitterfmu validate``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from xml.etree.ElementTree import Element, SubElement, fromstring

from fmukit.units import ARCSEC_PER_RAD, DEG_PER_RAD, LBF, MICRO_G

__all__ = [
    "UNITS",
    "UnitDef",
    "UnitError",
    "complete_model_description",
    "check_model_description",
    "CAPABILITIES",
]

#: Capability flags written to ``<CoSimulation>``.
CAPABILITIES = {
    "canHandleVariableCommunicationStepSize": "true",
    "canGetAndSetFMUstate": "true",
    "canSerializeFMUstate": "true",
}


class UnitError(ValueError):
    """A variable uses a unit that has no definition."""


@dataclass(frozen=True)
class UnitDef:
    """SI unit as FMI 2.0 ``<Unit>``: base-unit exponents and display units.

    Parameters
    ----------
    base : dict of str to int
        Exponents of ``kg, m, s, A, K, mol, cd, rad``.
    display : dict of str to float
        Display unit name -> factor (display value = factor * value).
    """

    base: dict[str, int] = field(default_factory=dict)
    display: dict[str, float] = field(default_factory=dict)


_ANGLE_DISPLAY = {"arcsec": ARCSEC_PER_RAD, "deg": DEG_PER_RAD}

#: Units the project uses.  Add an entry here before using a new unit.
UNITS: dict[str, UnitDef] = {
    "1": UnitDef(),
    "s": UnitDef({"s": 1}),
    "Hz": UnitDef({"s": -1}),
    "m": UnitDef({"m": 1}, {"um": 1e6, "mm": 1e3}),
    "m/s": UnitDef({"m": 1, "s": -1}),
    "m/s2": UnitDef({"m": 1, "s": -2}, {"ug": 1.0 / MICRO_G}),
    "kg": UnitDef({"kg": 1}),
    "rad": UnitDef({"rad": 1}, _ANGLE_DISPLAY),
    "rad/s": UnitDef({"rad": 1, "s": -1}, {"arcsec/s": ARCSEC_PER_RAD, "deg/s": DEG_PER_RAD}),
    "rad/s2": UnitDef({"rad": 1, "s": -2}, {"arcsec/s2": ARCSEC_PER_RAD}),
    "N": UnitDef({"kg": 1, "m": 1, "s": -2}, {"lbf": 1.0 / LBF}),
    "N.m": UnitDef({"kg": 1, "m": 2, "s": -2}),
    "N.m.s": UnitDef({"kg": 1, "m": 2, "s": -1}),
    "N/m": UnitDef({"kg": 1, "s": -2}),
    "N.s/m": UnitDef({"kg": 1, "s": -1}),
    "kg.m2": UnitDef({"kg": 1, "m": 2}),
    "V": UnitDef({"kg": 1, "m": 2, "s": -3, "A": -1}),
    "A": UnitDef({"A": 1}, {"mA": 1e3}),
    "W": UnitDef({"kg": 1, "m": 2, "s": -3}),
    "F": UnitDef({"kg": -1, "m": -2, "s": 4, "A": 2}, {"uF": 1e6}),
    "C": UnitDef({"s": 1, "A": 1}),
    "C/m": UnitDef({"m": -1, "s": 1, "A": 1}),
    "N/V": UnitDef({"m": -1, "s": 1, "A": 1}),
    "m/V": UnitDef({"kg": -1, "m": -1, "s": 3, "A": 1}),
    "V/s": UnitDef({"kg": 1, "m": 2, "s": -4, "A": -1}),
    "K": UnitDef({"K": 1}),
}

_BASE_ORDER = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
_SCHEMA_ORDER = ("CoSimulation", "ModelExchange", "UnitDefinitions", "TypeDefinitions",
                 "LogCategories", "DefaultExperiment", "VendorAnnotations", "ModelVariables",
                 "ModelStructure")


def _unit_element(name: str, unit: UnitDef) -> Element:
    el = Element("Unit", {"name": name})
    SubElement(el, "BaseUnit", {k: str(unit.base[k]) for k in _BASE_ORDER if k in unit.base})
    for disp, factor in unit.display.items():
        SubElement(el, "DisplayUnit", {"name": disp, "factor": repr(float(factor))})
    return el


def _insert_in_schema_order(root: Element, child: Element) -> None:
    rank = _SCHEMA_ORDER.index(child.tag)
    for pos, existing in enumerate(list(root)):
        if existing.tag in _SCHEMA_ORDER and _SCHEMA_ORDER.index(existing.tag) > rank:
            root.insert(pos, child)
            return
    root.append(child)


def complete_model_description(root: Element, slave) -> Element:
    """Add units, an exact ModelStructure and capability flags to ``root`` in place.

    Parameters
    ----------
    root : xml.etree.ElementTree.Element
        ``<fmiModelDescription>`` as written by ``Fmi2Slave.to_xml``.
    slave : fmukit.slave.FmuSlave
        The slave instance whose declarations produced ``root``.

    Returns
    -------
    xml.etree.ElementTree.Element
        ``root``.

    Raises
    ------
    UnitError
        If a Real uses a unit missing from :data:`UNITS`.
    KeyError
        If an output depends on a name that is not an input of the slave.
    """
    specs = slave.variable_specs
    ranges = getattr(slave, "variable_ranges", {})
    variables = root.find("ModelVariables")
    elements = list(variables)
    if len(elements) != len(specs):
        raise ValueError(f"model description of {slave.modelName!r} has {len(elements)} "
                         f"variables; the slave declares {len(specs)}")
    index = {}  # name -> 1-based position in ModelVariables
    used_units: list[str] = []
    for pos, (el, spec) in enumerate(zip(elements, specs), start=1):
        if el.get("name") != spec.name:
            raise ValueError(f"variable {pos} of {slave.modelName!r} is {el.get('name')!r}; "
                             f"expected {spec.name!r}")
        index[spec.name] = pos
        if spec.type == "Real":
            if spec.unit not in UNITS:
                raise UnitError(f"variable {spec.name!r} of {slave.modelName!r} has unit "
                                f"{spec.unit!r}; expected one of {sorted(UNITS)} (add it to "
                                "fmukit.modeldesc.UNITS)")
            real = el.find("Real")
            real.set("unit", spec.unit)
            if real.get("start") is not None:  # pythonfmu writes 16 digits: not bit exact
                real.set("start", repr(slave.get_real([spec.value_reference])[0]))
            if spec.unit not in used_units:
                used_units.append(spec.unit)
            for attr, bound in zip(("min", "max"), ranges.get(spec.name, ())):
                if math.isfinite(bound):
                    real.set(attr, repr(bound))

    # Capability flags.
    cs = root.find("CoSimulation")
    for key, value in CAPABILITIES.items():
        cs.set(key, value)

    # Units.
    old = root.find("UnitDefinitions")
    if old is not None:
        root.remove(old)
    if used_units:
        units = Element("UnitDefinitions")
        for name in sorted(used_units):
            units.append(_unit_element(name, UNITS[name]))
        _insert_in_schema_order(root, units)

    # ModelStructure.
    old = root.find("ModelStructure")
    if old is not None:
        root.remove(old)
    structure = SubElement(root, "ModelStructure")
    inputs = {s.name for s in specs if s.causality == "input"}
    parameters = [s.name for s in specs
                  if s.causality == "parameter" and s.initial in (None, "exact")]
    outputs = [s for s in specs if s.causality == "output"]
    if outputs:
        node = SubElement(structure, "Outputs")
        for spec in outputs:
            deps = slave._dependency_names(spec)
            for dep in deps:
                if dep not in inputs:
                    raise KeyError(f"output {spec.name!r} of {slave.modelName!r} depends on "
                                   f"{dep!r}, which is not an input")
            _unknown(node, index[spec.name], sorted({index[d] for d in deps}),
                     spec.dependencies_kind)
    initial = []
    for spec in specs:
        if spec.causality == "output" and spec.initial in (None, "approx", "calculated"):
            deps = {index[d] for d in slave._dependency_names(spec)}
            deps |= {index[p] for p in parameters}
            initial.append((index[spec.name], sorted(deps)))
        elif spec.causality == "calculatedParameter":
            initial.append((index[spec.name], sorted(index[p] for p in parameters)))
    if initial:
        node = SubElement(structure, "InitialUnknowns")
        for pos, deps in sorted(initial):
            _unknown(node, pos, deps, "dependent")
    return root


def _unknown(parent: Element, pos: int, deps: Iterable[int], kind: str) -> None:
    deps = list(deps)
    SubElement(parent, "Unknown", {
        "index": str(pos),
        "dependencies": " ".join(map(str, deps)),
        "dependenciesKind": " ".join([kind] * len(deps)),
    })


def check_model_description(xml: bytes | str) -> list[str]:
    """Return the project-specific problems of a model description.

    Checks: every output has a ``dependencies`` attribute; every Real declares a unit
    that is defined in ``UnitDefinitions``; ``canGetAndSetFMUstate="true"``;
    ``InitialUnknowns`` is present when some output is calculated.  An FMI 3.0 model
    description gets the same checks in its own terms (Float64, ``Output`` and
    ``InitialUnknown`` elements, ``canGetAndSetFMUState``).

    Parameters
    ----------
    xml : bytes or str
        Content of ``modelDescription.xml``.

    Returns
    -------
    list of str
        One sentence per problem; empty if none.
    """
    root = fromstring(xml)
    if root.get("fmiVersion") == "3.0":
        return _check_fmi3(root)
    problems: list[str] = []
    cs = root.find("CoSimulation")
    if cs is None:
        problems.append("modelDescription.xml has no CoSimulation element; expected an FMI 2.0 "
                        "co-simulation FMU")
    elif cs.get("canGetAndSetFMUstate") != "true":
        problems.append(f"CoSimulation has canGetAndSetFMUstate="
                        f"{cs.get('canGetAndSetFMUstate')!r}; expected 'true'")
    defined = {u.get("name") for u in root.iterfind("UnitDefinitions/Unit")}
    variables = list(root.iterfind("ModelVariables/ScalarVariable"))
    for sv in variables:
        real = sv.find("Real")
        if real is None:
            continue
        unit = real.get("unit")
        if unit is None and real.get("declaredType"):
            td = root.find(f"TypeDefinitions/SimpleType[@name='{real.get('declaredType')}']/Real")
            unit = td.get("unit") if td is not None else None
        if unit is None:
            problems.append(f"Real variable {sv.get('name')!r} has no unit; expected an SI unit "
                            "('1' if dimensionless)")
        elif unit not in defined:
            problems.append(f"Real variable {sv.get('name')!r} has unit {unit!r}, which "
                            "UnitDefinitions does not define")
    for unknown in root.iterfind("ModelStructure/Outputs/Unknown"):
        if unknown.get("dependencies") is None:
            pos = int(unknown.get("index"))
            name = variables[pos - 1].get("name") if 0 < pos <= len(variables) else pos
            problems.append(f"output {name!r} has no dependencies attribute; expected the exact "
                            "list of inputs it feeds through ('' for none)")
    calculated_outputs = [sv for sv in variables if sv.get("causality") == "output"
                          and sv.get("initial", "calculated") in ("approx", "calculated")]
    if calculated_outputs and root.find("ModelStructure/InitialUnknowns") is None:
        problems.append(f"ModelStructure has no InitialUnknowns; expected entries for "
                        f"{len(calculated_outputs)} calculated outputs")
    return problems


def _check_fmi3(root: Element) -> list[str]:
    """:func:`check_model_description` for an FMI 3.0 ``fmiModelDescription``."""
    problems: list[str] = []
    cs = root.find("CoSimulation")
    if cs is None:
        problems.append("modelDescription.xml has no CoSimulation element; expected an FMI 3.0 "
                        "co-simulation FMU")
    elif cs.get("canGetAndSetFMUState") != "true":
        problems.append(f"CoSimulation has canGetAndSetFMUState="
                        f"{cs.get('canGetAndSetFMUState')!r}; expected 'true'")
    defined = {u.get("name") for u in root.iterfind("UnitDefinitions/Unit")}
    names = {v.get("valueReference"): v.get("name") for v in root.find("ModelVariables")}
    for v in root.iterfind("ModelVariables/Float64"):
        unit = v.get("unit")
        if unit is None and v.get("declaredType"):
            td = root.find(f"TypeDefinitions/Float64Type[@name='{v.get('declaredType')}']")
            unit = td.get("unit") if td is not None else None
        if unit is None:
            problems.append(f"Float64 variable {v.get('name')!r} has no unit; expected an SI "
                            "unit ('1' if dimensionless)")
        elif unit not in defined:
            problems.append(f"Float64 variable {v.get('name')!r} has unit {unit!r}, which "
                            "UnitDefinitions does not define")
    for out in root.iterfind("ModelStructure/Output"):
        if out.get("dependencies") is None:
            problems.append(f"output {names.get(out.get('valueReference'))!r} has no "
                            "dependencies attribute; expected the exact list of inputs it "
                            "feeds through ('' for none)")
    calculated = [v for v in root.find("ModelVariables") if v.get("causality") == "output"
                  and v.get("initial", "calculated") in ("approx", "calculated")]
    if calculated and root.find("ModelStructure/InitialUnknown") is None:
        problems.append(f"ModelStructure has no InitialUnknown; expected entries for "
                        f"{len(calculated)} calculated outputs")
    return problems
