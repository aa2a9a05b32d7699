"""The FMI 3.0 model description of a native FMU, made from its FMI 2.0 one.

A native FMU built with ``fmi=3`` has the same variables, value references, units,
causality, variability, start values, ModelStructure and DefaultExperiment as its FMI 2.0
twin, written the FMI 3.0 way: a ``Real`` is a ``Float64``, an ``Integer`` an ``Int32``,
a String's start value a ``<Start>`` element, ``ModelStructure`` dependencies are value
references instead of indices, a ``time`` variable is the independent one, the GUID is an ``instantiationToken`` (a new one: the
binaries differ), and the C sources are listed in ``sources/buildDescription.xml``.
"""

from __future__ import annotations

import uuid
from collections.abc import Sequence
from xml.etree import ElementTree as ET

__all__ = ["FMI3_TYPES", "Fmi3ConversionError", "build_description", "fmi3_model_description",
           "fmi3_token"]

#: FMI 2.0 variable type -> FMI 3.0 variable element (the C layer's types, jfmu.h).
FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String"}

_ROOT_ATTRS = ("modelName", "description", "author", "version", "copyright", "license",
               "generationTool", "generationDateAndTime", "variableNamingConvention")
#: FMI 2.0 ``<CoSimulation>`` attribute -> FMI 3.0 name (None: not in FMI 3.0).
_CS_ATTRS = {"modelIdentifier": "modelIdentifier", "needsExecutionTool": "needsExecutionTool",
             "canBeInstantiatedOnlyOncePerProcess": "canBeInstantiatedOnlyOncePerProcess",
             "canGetAndSetFMUstate": "canGetAndSetFMUState",
             "canSerializeFMUstate": "canSerializeFMUState",
             "providesDirectionalDerivative": "providesDirectionalDerivatives",
             "canHandleVariableCommunicationStepSize":
                 "canHandleVariableCommunicationStepSize",
             "canInterpolateInputs": "canInterpolateInputs",
             "maxOutputDerivativeOrder": "maxOutputDerivativeOrder"}
_VAR_ATTRS = ("name", "valueReference", "description", "causality", "variability", "initial")
_TYPE_ATTRS = ("declaredType", "quantity", "unit", "displayUnit", "relativeQuantity", "min",
               "max", "nominal", "unbounded", "start", "reinit")
_STRUCTURE = (("Outputs", "Output"), ("Derivatives", "ContinuousStateDerivative"),
              ("InitialUnknowns", "InitialUnknown"))


class Fmi3ConversionError(ValueError):
    """An FMI 2.0 model description holds something the FMI 3.0 writer does not map."""


def fmi3_token(guid: str) -> str:
    """The FMI 3.0 instantiation token of the native FMU whose FMI 2.0 GUID is ``guid``.

    Parameters
    ----------
    guid : str
        GUID of the FMI 2.0 native FMU.
    """
    return "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "jitterfmu-native-fmi3:" + guid)) + "}"


def _copy(src: ET.Element, dst: ET.Element, names) -> None:
    for name in names:
        if src.get(name) is not None:
            dst.set(name, src.get(name))


def _typed(sv: ET.Element) -> ET.Element:
    typed = next((c for c in sv if c.tag in FMI3_TYPES), None)
    if typed is None:
        kinds = ", ".join(c.tag for c in sv) or "no type element"
        raise Fmi3ConversionError(f"variable {sv.get('name')!r} has {kinds}; the FMI 3.0 "
                                  "writer maps Real, Integer, Boolean and String only")
    return typed


def _variable(sv: ET.Element, vr_of_index: dict) -> ET.Element:
    typed = _typed(sv)
    out = ET.Element(FMI3_TYPES[typed.tag])
    _copy(sv, out, _VAR_ATTRS)
    if typed.tag == "String":
        _copy(typed, out, ("declaredType",))
        if typed.get("start") is not None:
            ET.SubElement(out, "Start", {"value": typed.get("start")})
    else:
        _copy(typed, out, _TYPE_ATTRS)
        if typed.get("derivative") is not None:   # an index in 2.0, a value reference in 3.0
            out.set("derivative", vr_of_index[int(typed.get("derivative"))])
    return out


def _type_definitions(types: ET.Element) -> ET.Element:
    out = ET.Element("TypeDefinitions")
    for simple in types.iterfind("SimpleType"):
        typed = _typed(simple)
        td = ET.SubElement(out, FMI3_TYPES[typed.tag] + "Type")
        _copy(simple, td, ("name", "description"))
        _copy(typed, td, [a for a in _TYPE_ATTRS if a not in ("start", "declaredType",
                                                              "reinit")])
    return out


def fmi3_model_description(root: ET.Element) -> ET.Element:
    """The FMI 3.0 co-simulation model description equal to FMI 2.0 ``root``.

    Parameters
    ----------
    root : Element
        ``fmiModelDescription`` of an FMI 2.0 native FMU (as written by
        :func:`nativefmu.build.native_model_description`).

    Returns
    -------
    Element
        ``fmiModelDescription fmiVersion="3.0"``, instantiation token from
        :func:`fmi3_token`.

    Raises
    ------
    Fmi3ConversionError
        If a variable or type is of a kind the writer does not map (Enumeration).
    """
    out = ET.Element("fmiModelDescription", {"fmiVersion": "3.0"})
    _copy(root, out, _ROOT_ATTRS[:1])
    out.set("instantiationToken", fmi3_token(root.get("guid", "")))
    _copy(root, out, _ROOT_ATTRS[1:])
    cs2 = root.find("CoSimulation")
    cs = ET.SubElement(out, "CoSimulation")
    for old, new in _CS_ATTRS.items():
        if cs2.get(old) is not None:
            cs.set(new, cs2.get(old))
    for tag in ("UnitDefinitions", "TypeDefinitions", "LogCategories", "DefaultExperiment"):
        part = root.find(tag)
        if tag == "UnitDefinitions":   # with the unit of time, the independent variable
            part = ET.fromstring(ET.tostring(part)) if part is not None else ET.Element(tag)
            if part.find("Unit[@name='s']") is None:
                ET.SubElement(ET.SubElement(part, "Unit", {"name": "s"}), "BaseUnit",
                              {"s": "1"})
        if part is None:
            continue
        if tag == "TypeDefinitions":
            part = _type_definitions(part)
        elif tag == "LogCategories":
            part = ET.fromstring(ET.tostring(part).replace(b"fmi2", b"fmi3"))
        out.append(part)
    variables = list(root.iterfind("ModelVariables/ScalarVariable"))
    vr_of_index = {i: sv.get("valueReference") for i, sv in enumerate(variables, start=1)}
    mv = ET.SubElement(out, "ModelVariables")
    if any(sv.get("name") == "time" for sv in variables):
        raise Fmi3ConversionError("the model has a variable named 'time', the name of the "
                                  "independent variable FMI 3.0 requires; rename it")
    # FMI 3.0 wants one independent variable: time, on a value reference of its own
    # (after every other one, so the C layer's tables are those of the FMI 2.0 twin)
    ET.SubElement(mv, "Float64", {
        "name": "time", "valueReference": str(1 + max(int(v) for v in vr_of_index.values())),
        "causality": "independent", "variability": "continuous",
        "description": "simulation time", "unit": "s"})
    for sv in variables:
        mv.append(_variable(sv, vr_of_index))
    ms = ET.SubElement(out, "ModelStructure")
    for group, tag in _STRUCTURE:
        for unknown in root.iterfind(f"ModelStructure/{group}/Unknown"):
            node = ET.SubElement(ms, tag, {"valueReference": vr_of_index[int(unknown.get("index"))]})
            deps = unknown.get("dependencies")
            if deps is not None:
                node.set("dependencies", " ".join(vr_of_index[int(i)] for i in deps.split()))
                _copy(unknown, node, ("dependenciesKind",))
    return out


def build_description(model_identifier: str, c_files: Sequence[str]) -> bytes:
    """``sources/buildDescription.xml`` of an FMI 3.0 native FMU.

    Parameters
    ----------
    model_identifier : str
        The FMU's modelIdentifier.
    c_files : sequence of str
        The ``.c`` files of ``sources/``, in compile order.
    """
    root = ET.Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    config = ET.SubElement(root, "BuildConfiguration", {"modelIdentifier": model_identifier})
    files = ET.SubElement(config, "SourceFileSet", {"language": "C99"})
    for name in c_files:
        ET.SubElement(files, "SourceFile", {"name": name})
    ET.SubElement(config, "Library", {"name": "m", "external": "true",
                                      "description": "the C maths library (libm)"})
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
