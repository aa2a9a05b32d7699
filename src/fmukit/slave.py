"""Base class for the project's FMI 2.0 co-simulation slaves.

A slave subclasses :class:`FmuSlave`, declares its variables in ``__init__`` and
implements :meth:`FmuSlave.do_step`.  All Real variables live in one contiguous
``float64`` array, so the FMI getters and setters are one fancy-index each, and a
block of variables (``y[1]`` ... ``y[n]``) is a numpy view that ``do_step`` reads
and writes in place.

Example
-------
>>> class Filter(FmuSlave):
...     state_attributes = ("x",)
...     def __init__(self, **kwargs):
...         super().__init__(**kwargs)
...         self.add_parameter("a", 0.5, unit="1", description="pole")
...         self.add_input("u", unit="V")
...         self.add_output("y", unit="V", depends_on=["u"])
...         self.x = np.zeros(1)
...     def do_step(self, current_time, step_size):
...         self.x[0] = self.a * self.x[0] + self.u
...         self.y = self.x[0] + self.u
...         return True

Scalar Real variables read and write like attributes (``self.u``); they are
properties of a private per-instance subclass, backed by the value array.
Integer, Boolean and String variables are plain attributes.

The FMU state (``fmi2GetFMUstate``) holds a copy of every variable value and a deep
copy of every attribute named in :attr:`FmuSlave.state_attributes`; restoring it
writes numpy arrays back in place, so views and aliases the slave keeps stay valid.
Serialized states use the plain, versioned byte layout of :mod:`fmukit.state` (data
only: no pickle, nothing is imported or called on restore) and are checked against
the slave's declared variables and state attributes before anything is written.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from pythonfmu import Fmi2Slave
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Status, Fmi2Variability
from pythonfmu.variables import Boolean, Integer, Real, String

from fmukit.modeldesc import complete_model_description
from fmukit.state import FmuStateError, decode_state, encode_state

__all__ = [
    "FmuSlave",
    "VariableSpec",
    "DeclarationError",
    "FmuStateError",
]

_CAUSALITIES = {"parameter", "calculatedParameter", "input", "output", "local"}
_VARIABILITIES = {"constant", "fixed", "tunable", "discrete", "continuous"}
_INITIALS = {"exact", "approx", "calculated", None}
_KINDS = {"dependent", "constant", "fixed", "tunable", "discrete"}


class DeclarationError(ValueError):
    """A variable declaration is inconsistent."""


@dataclass(frozen=True)
class VariableSpec:
    """What the model description needs to know about one variable.

    Parameters
    ----------
    name : str
        FMI variable name, e.g. ``"u"`` or ``"y[3]"``.
    type : str
        ``"Real"``, ``"Integer"``, ``"Boolean"`` or ``"String"``.
    value_reference : int
        Value reference, unique over all variables of the slave.
    causality, variability : str
        FMI 2.0 causality and variability.
    initial : str or None
        FMI 2.0 ``initial`` attribute, None to omit it.
    unit : str or None
        Unit of a Real (must exist in :data:`fmukit.modeldesc.UNITS`), None otherwise.
    depends_on : tuple of str or None
        For an output: the names of the inputs it depends on directly (empty:
        none).  None for other causalities.
    dependencies_kind : str
        FMI 2.0 ``dependenciesKind`` used for every dependency of this output.
    """

    name: str
    type: str
    value_reference: int
    causality: str
    variability: str
    initial: str | None
    unit: str | None = None
    depends_on: tuple[str, ...] | None = None
    dependencies_kind: str = "dependent"
    description: str = ""
    block: str | None = field(default=None, compare=False)


def _finite(value: Any) -> bool:
    """Whether every float or complex in ``value`` (nested lists, tuples, dicts) is finite."""
    if isinstance(value, np.ndarray):
        return value.dtype.kind not in "fc" or bool(np.all(np.isfinite(value)))
    if isinstance(value, (float, complex, np.floating, np.complexfloating)):
        return bool(np.isfinite(value))
    if isinstance(value, (list, tuple)):
        return all(_finite(v) for v in value)
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    return True


#: The longest step one ``do_step`` takes (s), as the native FMUs' ``JF_MAX_STEP``.
MAX_STEP = 1e4


def _enum(enum_type, value):
    return None if value is None else enum_type[value]


class FmuSlave(Fmi2Slave):
    """Co-simulation slave with typed, unit-aware, array-backed variables.

    Subclasses call ``super().__init__(**kwargs)`` first, then declare variables
    with :meth:`add_input`, :meth:`add_output`, :meth:`add_parameter`,
    :meth:`add_real`, :meth:`add_real_block`, :meth:`add_integer`,
    :meth:`add_boolean` and :meth:`add_string`, and implement ``do_step``.

    Class attributes
    ----------------
    state_attributes : tuple of str
        Names of the internal attributes (numpy arrays, scalars, lists, ...) that the
        FMU state must cover beyond the registered variables, e.g. the discrete
        state vector and the step counter.
    model_identifier : str or None
        FMI modelIdentifier; set by the build script.  Defaults to the class name.
    description : str or None
        Model description written to modelDescription.xml.

    Parameters
    ----------
    **kwargs
        Passed by the FMI wrapper: ``instance_name``, ``resources`` (path of the
        unpacked ``resources/`` folder), ``visible``, ``logger``.
    """

    state_attributes: ClassVar[tuple[str, ...]] = ()
    model_identifier: ClassVar[str | None] = None
    description: ClassVar[str | None] = None

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Bound the work of a subclass's ``do_step``: a step that is not positive and
        finite, or longer than :data:`MAX_STEP`, is refused (logged, ``False``) before
        the slave loops over its samples (``doStep(t, 1e15)`` never returned)."""
        super().__init_subclass__(**kwargs)
        step = cls.__dict__.get("do_step")
        if step is None or getattr(step, "bounded", False):
            return

        def do_step(self, current_time, step_size):
            if not (0.0 < step_size <= MAX_STEP and math.isfinite(current_time)):
                self.log(f"doStep: a step of {step_size!r} s from t = {current_time!r} s; "
                         f"expected a positive step of at most {MAX_STEP:g} s (step in "
                         "pieces)", Fmi2Status.error)
                return False
            bad = self._first_nonfinite("input")
            bad = (f"input {bad} is not a finite number" if bad is not None
                   else None if self._refused is None
                   else f"{self._refused} (refused by setReal)")
            if bad is not None:   # never a NaN output reported with OK
                self.log(f"doStep from t = {current_time!r} s: {bad}; nothing was stepped "
                         "(set a finite value)", Fmi2Status.error)
                return False
            done = step(self, current_time, step_size)
            bad = self._first_nonfinite("output") if done else None
            if bad is not None:
                self.log(f"doStep from t = {current_time!r} s: output {bad} after the step is "
                         "not a finite number (an input or parameter far out of range?); the "
                         "step ends with an error", Fmi2Status.error)
                return False
            return done

        do_step.__doc__, do_step.bounded = step.__doc__, True
        cls.do_step = do_step

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        cls = type(self)
        # Private subclass per instance: holds the properties of scalar Reals, so two
        # instances (or two FMUs sharing a slave class) never see each other's layout.
        self.__class__ = type(cls.__name__, (cls,), {"__module__": cls.__module__,
                                                       "__qualname__": cls.__qualname__})
        self._fmukit_base_class = cls
        self.modelName = cls.model_identifier or cls.__name__
        self._real_values = np.zeros(16)
        self._n_real = 0
        self._real_slot: dict[int, int] = {}
        self._real_blocks: dict[str, tuple[int, int]] = {}
        self._other_attr: dict[int, tuple[str, type]] = {}
        self._specs: dict[int, VariableSpec] = {}
        self._by_name: dict[str, VariableSpec] = {}
        self._index_cache: dict[tuple, Any] = {}
        self._refused: str | None = None   # the last setReal's non-finite value
        #: declared ``(min, max)`` of Real variables, by name (see :meth:`declare_range`)
        self.variable_ranges: dict[str, tuple[float, float]] = {}

    # ------------------------------------------------------------------ resources
    @property
    def resource_dir(self) -> Path:
        """Path of the FMU's unpacked ``resources/`` folder."""
        if self.resources is None:
            raise FileNotFoundError(f"slave {self.instance_name!r} was given no resources folder")
        return Path(self.resources)

    def resource_path(self, name: str) -> Path:
        """Return the path of resource file ``name``, checking that it exists.

        Parameters
        ----------
        name : str
            File name inside ``resources/`` (as given in ``FmuSpec.resources``).
        """
        path = self.resource_dir / name
        if not path.is_file():
            raise FileNotFoundError(
                f"resource {name!r} of slave {self.instance_name!r} not found at {path}"
            )
        return path

    # ------------------------------------------------------------------ declaration
    @property
    def variable_specs(self) -> list[VariableSpec]:
        """All declared variables in value-reference order."""
        return [self._specs[vr] for vr in sorted(self._specs)]

    def declare_range(self, name: str, lo: float, hi: float) -> None:
        """Declare the physical range of a Real variable (FMI ``min`` and ``max``).

        A value outside it means the model has left its validity (a diverging loop, a
        strain no material survives); a master may stop the run there.

        Parameters
        ----------
        name : str
            A declared Real variable.
        lo, hi : float
            Bounds in the variable's unit; ``-inf`` or ``inf`` for an open side.
        """
        spec = self._by_name.get(name)
        if spec is None or spec.type != "Real":
            raise DeclarationError(f"cannot declare a range for {name!r}: it is not a "
                                   "declared Real variable")
        if not lo < hi or math.isnan(lo) or math.isnan(hi):
            raise DeclarationError(f"range of {name!r} is [{lo!r}, {hi!r}]; expected "
                                   "min < max")
        self.variable_ranges[name] = (float(lo), float(hi))

    def add_input(self, name: str, *, unit: str, start: float = 0.0, description: str = "",
                  variability: str = "continuous") -> None:
        """Declare a scalar Real input, readable as ``self.<name>``.

        Parameters
        ----------
        name : str
            Variable name (a Python identifier).
        unit : str
            SI unit, e.g. ``"V"``, ``"rad"``, ``"1"`` for dimensionless.
        start : float
            Start value.
        description : str
            One line.
        variability : {"continuous", "discrete"}
            FMI variability.
        """
        self.add_real(name, causality="input", variability=variability, start=start,
                      unit=unit, description=description)

    def add_output(self, name: str, *, unit: str, depends_on: Iterable[str],
                   start: float = 0.0, description: str = "",
                   variability: str = "continuous", dependencies_kind: str = "dependent") -> None:
        """Declare a scalar Real output with its direct input dependencies.

        Parameters
        ----------
        name : str
            Variable name.
        unit : str
            SI unit.
        depends_on : iterable of str
            Inputs the output depends on *within the same step* (direct
            feedthrough).  Empty for outputs computed from the state only.  A block
            name stands for all its elements.
        start : float
            Value before the first step (the output has ``initial="calculated"``).
        description : str
            One line.
        variability : {"continuous", "discrete"}
            FMI variability.
        dependencies_kind : str
            FMI ``dependenciesKind`` of every listed dependency.
        """
        self.add_real(name, causality="output", variability=variability, start=start,
                      unit=unit, description=description, depends_on=depends_on,
                      dependencies_kind=dependencies_kind)

    def add_parameter(self, name: str, start: float | int | bool | str, *, unit: str | None = None,
                      description: str = "", tunable: bool = False) -> None:
        """Declare a parameter whose FMI type follows the type of ``start``.

        Parameters
        ----------
        name : str
            Variable name.
        start : float, int, bool or str
            Default value; ``float`` gives a Real (``unit`` required), ``int`` an
            Integer, ``bool`` a Boolean, ``str`` a String.
        unit : str, optional
            SI unit of a Real parameter.
        description : str
            One line.
        tunable : bool
            True for variability ``tunable`` (may change between steps), else ``fixed``.
        """
        variability = "tunable" if tunable else "fixed"
        if isinstance(start, bool):
            self.add_boolean(name, start, causality="parameter", variability=variability,
                             description=description)
        elif isinstance(start, (int, np.integer)):
            self.add_integer(name, int(start), causality="parameter", variability=variability,
                             description=description)
        elif isinstance(start, str):
            self.add_string(name, start, causality="parameter", variability=variability,
                            description=description)
        elif isinstance(start, (float, np.floating)):
            if unit is None:
                raise DeclarationError(f"Real parameter {name!r} has no unit; expected an SI unit"
                                       " such as 'm' or '1' for dimensionless")
            self.add_real(name, causality="parameter", variability=variability,
                          start=float(start), unit=unit, description=description)
        else:
            raise DeclarationError(f"parameter {name!r} has start value of type "
                                   f"{type(start).__name__}; expected float, int, bool or str")

    def add_real(self, name: str, *, causality: str = "local", variability: str = "continuous",
                 initial: str | None = None, start: float = 0.0, unit: str,
                 description: str = "", depends_on: Iterable[str] | None = None,
                 dependencies_kind: str = "dependent") -> None:
        """Declare one scalar Real variable, readable and writable as ``self.<name>``.

        Parameters
        ----------
        name : str
            Variable name; a Python identifier so that ``self.<name>`` works.
        causality : str
            ``parameter``, ``calculatedParameter``, ``input``, ``output`` or ``local``.
        variability : str
            ``constant``, ``fixed``, ``tunable``, ``discrete`` or ``continuous``.
        initial : str or None
            ``exact``, ``approx``, ``calculated`` or None for the FMI default
            (``exact`` for parameters, ``calculated`` for outputs and locals; inputs
            carry none).
        start : float
            Start value (written to the XML unless ``initial`` is ``calculated``).
        unit : str
            SI unit, ``"1"`` for dimensionless.
        description : str
            One line.
        depends_on : iterable of str, optional
            Required for outputs: the inputs with direct feedthrough (may be empty).
        dependencies_kind : str
            FMI ``dependenciesKind`` of every dependency.
        """
        if not name.isidentifier():
            raise DeclarationError(f"scalar Real name {name!r} is not a Python identifier")
        slot = self._declare_real(name, causality, variability, initial, float(start), unit,
                                  description, depends_on, dependencies_kind, block=None)
        prop = property(lambda s, k=slot: s._real_values[k],
                        lambda s, v, k=slot: s._real_values.__setitem__(k, v))
        setattr(type(self), name, prop)

    def add_real_block(self, name: str, size: int | None = None, *, names: Sequence[str] | None = None,
                       causality: str = "local", variability: str = "continuous",
                       initial: str | None = None, start: float | Sequence[float] = 0.0,
                       unit: str | Sequence[str], description: str = "",
                       depends_on: Iterable[str] | Sequence[Iterable[str]] | None = None,
                       dependencies_kind: str = "dependent") -> np.ndarray:
        """Declare a block of Real variables backed by one numpy view.

        The view is stored as ``self.<name>`` (shape ``(size,)``) and returned.
        ``do_step`` writes it in place (``self.y[:] = ...``); never rebind it.
        Declare all variables before keeping other references to a block.

        Parameters
        ----------
        name : str
            Block name and attribute name.
        size : int, optional
            Number of elements; element ``i`` is named ``name[i+1]`` (FMI/Modelica
            arrays are 1-based).  Give either ``size`` or ``names``.
        names : sequence of str, optional
            Explicit FMI names of the elements (e.g. ``["strain_longeron", ...]``).
        causality, variability, initial, description, dependencies_kind
            As in :meth:`add_real`, for every element.
        start : float or sequence of float, shape (size,)
            Start values.
        unit : str or sequence of str, shape (size,)
            SI unit(s).
        depends_on : iterable of str, or sequence of iterables, optional
            For outputs: inputs every element depends on, or one list per element.

        Returns
        -------
        numpy.ndarray, shape (size,)
            View on the value array.
        """
        if not name.isidentifier():
            raise DeclarationError(f"block name {name!r} is not a Python identifier")
        if names is None:
            if size is None:
                raise DeclarationError(f"block {name!r} has neither size nor names; give one")
            names = [f"{name}[{i + 1}]" for i in range(int(size))]
        elif size is not None and size != len(names):
            raise DeclarationError(f"block {name!r} has size {size} but {len(names)} names")
        n = len(names)
        starts = np.broadcast_to(np.asarray(start, dtype=float), (n,))
        units = [unit] * n if isinstance(unit, str) else list(unit)
        if len(units) != n:
            raise DeclarationError(f"block {name!r} has {n} elements but {len(units)} units")
        if depends_on is None or isinstance(depends_on, str):
            deps = [depends_on] * n
        else:
            deps_list = list(depends_on)
            if deps_list and not isinstance(deps_list[0], str):
                if len(deps_list) != n:
                    raise DeclarationError(f"block {name!r} has {n} elements but "
                                           f"{len(deps_list)} dependency lists")
                deps = deps_list
            else:
                deps = [deps_list] * n
        first = self._n_real
        for i in range(n):
            self._declare_real(names[i], causality, variability, initial, float(starts[i]),
                               units[i], description, deps[i], dependencies_kind, block=name)
        self._real_blocks[name] = (first, first + n)
        self._rebind_blocks()
        return getattr(self, name)

    def add_integer(self, name: str, start: int = 0, *, causality: str = "parameter",
                    variability: str = "fixed", initial: str | None = None,
                    description: str = "", depends_on: Iterable[str] | None = None) -> None:
        """Declare an Integer variable stored as the plain attribute ``self.<name>``.

        Parameters
        ----------
        name : str
            Variable name (a Python identifier).
        start : int
            Start value.
        causality, variability, initial, description, depends_on
            As in :meth:`add_real`.
        """
        self._declare_other(Integer, int, name, int(start), causality, variability, initial,
                            description, depends_on)

    def add_boolean(self, name: str, start: bool = False, *, causality: str = "parameter",
                    variability: str = "fixed", initial: str | None = None,
                    description: str = "", depends_on: Iterable[str] | None = None) -> None:
        """Declare a Boolean variable stored as the plain attribute ``self.<name>``.

        Parameters
        ----------
        name : str
            Variable name (a Python identifier).
        start : bool
            Start value.
        causality, variability, initial, description, depends_on
            As in :meth:`add_real`.
        """
        self._declare_other(Boolean, bool, name, bool(start), causality, variability, initial,
                            description, depends_on)

    def add_string(self, name: str, start: str = "", *, causality: str = "parameter",
                   variability: str = "fixed", initial: str | None = None,
                   description: str = "") -> None:
        """Declare a String variable stored as the plain attribute ``self.<name>``.

        Parameters
        ----------
        name : str
            Variable name (a Python identifier).
        start : str
            Start value.
        causality, variability, initial, description
            As in :meth:`add_real`.
        """
        self._declare_other(String, str, name, str(start), causality, variability, initial,
                            description, None)

    # ------------------------------------------------------------------ internals
    def _check(self, name, causality, variability, initial, depends_on, kind, type_name):
        if name in self._by_name:
            raise DeclarationError(f"variable {name!r} is declared twice")
        if causality not in _CAUSALITIES:
            raise DeclarationError(f"variable {name!r} has causality {causality!r}; "
                                   f"expected one of {sorted(_CAUSALITIES)}")
        if variability not in _VARIABILITIES:
            raise DeclarationError(f"variable {name!r} has variability {variability!r}; "
                                   f"expected one of {sorted(_VARIABILITIES)}")
        if initial not in _INITIALS:
            raise DeclarationError(f"variable {name!r} has initial {initial!r}; "
                                   "expected exact, approx, calculated or None")
        if kind not in _KINDS:
            raise DeclarationError(f"variable {name!r} has dependencies kind {kind!r}; "
                                   f"expected one of {sorted(_KINDS)}")
        if type_name != "Real" and variability == "continuous":
            raise DeclarationError(f"{type_name} variable {name!r} is continuous; "
                                   "expected discrete, fixed, tunable or constant")
        if causality == "output":
            if depends_on is None:
                raise DeclarationError(f"output {name!r} has no depends_on; list the inputs it "
                                       "feeds through directly, or [] for none")
            if isinstance(depends_on, str):
                raise DeclarationError(f"output {name!r} has depends_on={depends_on!r}; "
                                       "expected a list of input names")
            return tuple(depends_on)
        if depends_on:
            raise DeclarationError(f"{causality} {name!r} has depends_on; only outputs have "
                                   "input dependencies")
        return None

    def _declare_real(self, name, causality, variability, initial, start, unit, description,
                      depends_on, kind, block):
        deps = self._check(name, causality, variability, initial, depends_on, kind, "Real")
        if not isinstance(unit, str) or not unit:
            raise DeclarationError(f"Real variable {name!r} has unit {unit!r}; expected an SI "
                                   "unit such as 'm', or '1' for dimensionless")
        if not math.isfinite(start):
            raise DeclarationError(f"Real variable {name!r} has start {start}; expected finite")
        slot = self._n_real
        if slot == self._real_values.size:
            grown = np.zeros(2 * slot)
            grown[:slot] = self._real_values
            self._real_values = grown
            self._rebind_blocks()
        self._real_values[slot] = start
        self._n_real += 1
        needs_start = (initial in ("exact", "approx") or causality in ("input", "parameter")
                       or variability == "constant")
        var = Real(name, start=start if needs_start else None, causality=_enum(Fmi2Causality, causality),
                   variability=_enum(Fmi2Variability, variability),
                   initial=_enum(Fmi2Initial, initial), description=description or None,
                   getter=lambda s=self, k=slot: float(s._real_values[k]),
                   setter=lambda v, s=self, k=slot: s._real_values.__setitem__(k, v))
        self.register_variable(var, nested=False)
        vr = var.value_reference
        self._real_slot[vr] = slot
        self._register_spec(VariableSpec(name, "Real", vr, causality, variability, initial,
                                         unit, deps, kind, description, block))
        return slot

    def _declare_other(self, var_type, py_type, name, start, causality, variability, initial,
                       description, depends_on):
        type_name = var_type.__name__
        if not name.isidentifier():
            raise DeclarationError(f"{type_name} name {name!r} is not a Python identifier")
        deps = self._check(name, causality, variability, initial, depends_on, "dependent",
                           type_name)
        setattr(self, name, start)
        needs_start = (initial in ("exact", "approx") or causality in ("input", "parameter")
                       or variability == "constant")
        var = var_type(name, start=start if needs_start else None, causality=_enum(Fmi2Causality, causality),
                       variability=_enum(Fmi2Variability, variability),
                       initial=_enum(Fmi2Initial, initial), description=description or None,
                       getter=lambda s=self, a=name, t=py_type: t(getattr(s, a)),
                       setter=lambda v, s=self, a=name, t=py_type: setattr(s, a, t(v)))
        self.register_variable(var, nested=False)
        vr = var.value_reference
        self._other_attr[vr] = (name, var_type)
        self._register_spec(VariableSpec(name, type_name, vr, causality, variability, initial,
                                         None, deps, "dependent", description, None))

    def _register_spec(self, spec: VariableSpec) -> None:
        self._specs[spec.value_reference] = spec
        self._by_name[spec.name] = spec
        self._index_cache.clear()

    def _rebind_blocks(self) -> None:
        for block, (a, b) in self._real_blocks.items():
            object.__setattr__(self, block, self._real_values[a:b])

    def _first_nonfinite(self, causality: str) -> str | None:
        """``"name = value"`` of the first Real of ``causality`` that is not finite, or None."""
        key = ("nonfinite", causality)
        found = self._index_cache.get(key)
        if found is None:
            specs = [sp for sp in self._specs.values() if sp.type == "Real"
                     and sp.causality == causality and sp.value_reference in self._real_slot]
            found = (self._real_index([sp.value_reference for sp in specs]),
                     [sp.name for sp in specs])
            self._index_cache[key] = found
        idx, names = found
        values = self._real_values[idx]
        if np.all(np.isfinite(values)):
            return None
        k = int(np.flatnonzero(~np.isfinite(values))[0])
        return f"{names[k]} = {float(values[k])!r}"

    def _real_index(self, vrs) -> np.ndarray:
        key = tuple(vrs)
        idx = self._index_cache.get(key)
        if idx is None:
            try:
                idx = np.fromiter((self._real_slot[vr] for vr in key), dtype=np.intp,
                                  count=len(key))
            except KeyError as exc:
                raise TypeError(f"value reference {exc.args[0]} of {self.instance_name!r} is "
                                "not a Real variable") from None
            self._index_cache[key] = idx
        return idx

    def _dependency_names(self, spec: VariableSpec) -> list[str]:
        """Expand the block names in ``spec.depends_on`` into element names."""
        out: list[str] = []
        for dep in spec.depends_on or ():
            if dep in self._real_blocks and dep not in self._by_name:
                a, b = self._real_blocks[dep]
                out += [s.name for s in self._specs.values()
                        if s.type == "Real" and a <= self._real_slot[s.value_reference] < b]
            else:
                out.append(dep)
        return out

    # ------------------------------------------------------------------ FMI getters/setters
    def get_real(self, vrs: list[int]) -> list[float]:
        return self._real_values[self._real_index(vrs)].tolist()

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        """Set Real variables by value reference (``fmi2SetReal``).

        Parameters
        ----------
        vrs : list of int
            Value references.
        values : list of float
            One value per reference, in the variable's unit.

        A value that is not a finite number sets nothing: the call logs an error and the
        next ``doStep`` ends with Discard naming it (pythonfmu turns an exception here into
        Fatal), so no output is ever computed from it.
        """
        idx = self._real_index(vrs)
        values = np.asarray(values, dtype=float)
        if not np.all(np.isfinite(values)):
            k = int(np.flatnonzero(~np.isfinite(values))[0])
            spec = self._specs.get(vrs[k])
            name = spec.name if spec is not None else f"value reference {vrs[k]}"
            self._refused = f"{name} = {float(values[k])!r} is not a finite number"
            self.log(f"setReal: {self._refused}; nothing was set (set a finite value)",
                     Fmi2Status.error)
            return
        self._refused = None
        self._real_values[idx] = values

    def _get_other(self, vrs, var_type, py_type):
        out = []
        for vr in vrs:
            entry = self._other_attr.get(vr)
            if entry is None or entry[1] is not var_type:
                raise TypeError(f"value reference {vr} of {self.instance_name!r} is not an "
                                f"{var_type.__name__} variable")
            out.append(py_type(getattr(self, entry[0])))
        return out

    def _set_other(self, vrs, values, var_type, py_type):
        for vr, value in zip(vrs, values):
            entry = self._other_attr.get(vr)
            if entry is None or entry[1] is not var_type:
                raise TypeError(f"value reference {vr} of {self.instance_name!r} is not an "
                                f"{var_type.__name__} variable")
            setattr(self, entry[0], py_type(value))

    def get_integer(self, vrs: list[int]) -> list[int]:
        return self._get_other(vrs, Integer, int)

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        """Set Integer variables by value reference (``fmi2SetInteger``).

        Parameters
        ----------
        vrs : list of int
            Value references.
        values : list of int
            One value per reference, in the variable's unit.
        """
        self._set_other(vrs, values, Integer, int)

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        return self._get_other(vrs, Boolean, bool)

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        """Set Boolean variables by value reference (``fmi2SetBoolean``).

        Parameters
        ----------
        vrs : list of int
            Value references.
        values : list of bool
            One value per reference.
        """
        self._set_other(vrs, values, Boolean, bool)

    def get_string(self, vrs: list[int]) -> list[str]:
        return self._get_other(vrs, String, str)

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        """Set String variables by value reference (``fmi2SetString``).

        Parameters
        ----------
        vrs : list of int
            Value references.
        values : list of str
            One value per reference.
        """
        self._set_other(vrs, values, String, str)

    # ------------------------------------------------------------------ FMU state
    def _get_fmu_state(self) -> dict[str, Any]:
        """Snapshot every variable and every attribute in ``state_attributes``."""
        attrs = {}
        for name in type(self).state_attributes:
            if not hasattr(self, name):
                raise FmuStateError(f"state attribute {name!r} of {type(self).__name__} is not "
                                    "set; assign it in __init__")
            attrs[name] = copy.deepcopy(getattr(self, name))
        return {
            "real": self._real_values[: self._n_real].copy(),
            "other": {name: getattr(self, name) for name, _ in self._other_attr.values()},
            "attrs": attrs,
        }

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        """Restore a snapshot made by :meth:`_get_fmu_state`, all or nothing.

        The whole snapshot is checked against this slave's variables and
        ``state_attributes`` first (shapes, types, every float finite); on any mismatch
        :class:`FmuStateError` is raised and nothing is changed.  Then
        :meth:`_fmu_state_restored` checks and refreshes what the subclass derives
        from the state; if it raises, the previous state is written back and
        :class:`FmuStateError` is raised.  The snapshot itself stays intact.
        """
        self._check_fmu_state(state)
        before = FmuSlave._get_fmu_state(self)
        self._write_fmu_state(state)
        try:
            self._fmu_state_restored()
        except Exception as exc:  # noqa: BLE001 - any refusal by the subclass
            self._write_fmu_state(before)
            self._fmu_state_restored()
            raise FmuStateError(f"FMU state refused by slave {self.instance_name!r} "
                                f"({type(self).__name__}): {exc}; its previous state is "
                                "kept") from None

    def _fmu_state_restored(self) -> None:
        """Check and refresh what the slave derives from a restored state (override).

        Raise (any exception) to refuse the state; :meth:`_set_fmu_state` then writes
        the previous state back.
        """

    def _write_fmu_state(self, state: dict[str, Any]) -> None:
        self._real_values[: self._n_real] = state["real"]
        for name, value in state["other"].items():
            setattr(self, name, value)
        for name, saved in state["attrs"].items():
            current = getattr(self, name, None)
            if (isinstance(current, np.ndarray) and isinstance(saved, np.ndarray)
                    and current.shape == saved.shape and current.dtype == saved.dtype
                    and current.flags.writeable):
                current[...] = saved
            else:
                setattr(self, name, copy.deepcopy(saved))

    def _check_fmu_state(self, state: Any) -> None:
        """Raise FmuStateError unless ``state`` fits this slave exactly."""
        who = f"slave {self.instance_name!r} ({type(self).__name__})"
        if not isinstance(state, dict) or set(state) != {"real", "other", "attrs"}:
            raise FmuStateError(f"FMU state for {who} is not a dict with keys real, other, "
                                "attrs")
        real = state["real"]
        if not isinstance(real, np.ndarray) or real.dtype != np.float64 or real.ndim != 1:
            raise FmuStateError(f"FMU state for {who} has Real values of type "
                                f"{type(real).__name__}; expected a 1-d float64 array")
        if real.shape != (self._n_real,):
            raise FmuStateError(f"FMU state holds {real.shape[0]} Real values; {who} has "
                                f"{self._n_real}")
        if not np.all(np.isfinite(real)):
            bad = int(np.flatnonzero(~np.isfinite(real))[0])
            name = next(spec.name for vr, spec in self._specs.items()
                        if self._real_slot.get(vr) == bad)
            raise FmuStateError(f"FMU state for {who} sets Real {name!r} to {real[bad]}; "
                                "expected finite values")
        kinds = {name: var_type for name, var_type in self._other_attr.values()}
        other = state["other"]
        if not isinstance(other, dict) or set(other) != set(kinds):
            got = sorted(other) if isinstance(other, dict) else type(other).__name__
            raise FmuStateError(f"FMU state for {who} has Integer/Boolean/String variables "
                                f"{got}; expected {sorted(kinds)}")
        py_types = {Integer: (int,), Boolean: (bool,), String: (str,)}
        for name, value in other.items():
            expected = py_types[kinds[name]]
            if not isinstance(value, expected) or (expected == (int,) and isinstance(value, bool)):
                raise FmuStateError(f"FMU state for {who} sets {kinds[name].__name__} "
                                    f"{name!r} to a {type(value).__name__}")
        attrs = state["attrs"]
        names = set(type(self).state_attributes)
        if not isinstance(attrs, dict) or set(attrs) != names:
            got = sorted(attrs) if isinstance(attrs, dict) else type(attrs).__name__
            raise FmuStateError(f"FMU state for {who} has state attributes {got}; expected "
                                f"{sorted(names)}")
        for name, saved in attrs.items():
            current = getattr(self, name, None)
            if isinstance(current, np.ndarray) and current.flags.writeable and (
                    not isinstance(saved, np.ndarray) or saved.shape != current.shape):
                shape = saved.shape if isinstance(saved, np.ndarray) else type(saved).__name__
                raise FmuStateError(f"FMU state for {who} gives attribute {name!r} as {shape}; "
                                    f"expected an array of shape {current.shape}")
            if not _finite(saved):
                raise FmuStateError(f"FMU state for {who} gives attribute {name!r} a value "
                                    "that is not finite; expected finite values")

    @staticmethod
    def _fmu_state_to_bytes(state: dict[str, Any]) -> bytes:
        """Serialize a snapshot into the data-only layout of :mod:`fmukit.state`."""
        return encode_state(state)

    @staticmethod
    def _fmu_state_from_bytes(data: bytes) -> dict[str, Any]:
        """Rebuild a snapshot from bytes; :class:`FmuStateError` if they are not one."""
        state = decode_state(data)
        if not isinstance(state, dict) or set(state) != {"real", "other", "attrs"}:
            raise FmuStateError("serialized FMU state is not a dict with keys real, other, "
                                "attrs")
        return state

    # ------------------------------------------------------------------ XML
    def to_xml(self, model_options: dict[str, str] | None = None):
        """Return the complete model description (units, ModelStructure, flags)."""
        root = super().to_xml(model_options or {})
        complete_model_description(root, self)
        return root
