"""The keys of every file a user writes: scenario, campaign, uncertainty and sweep files.

One table per TOML table, one :class:`Key` per key, with its type, unit, default,
allowed values and an example.  The parsers take their lists of valid keys from here
(:func:`keys`), so a key they accept is a key this reference lists;
``docs/reference.md`` and ``jitterfmu keys`` are written from it (:func:`markdown`).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FILES", "Key", "Table", "keys", "markdown", "table", "text"]

REQUIRED = "required"


@dataclass(frozen=True)
class Key:
    """One key of a table.

    Attributes
    ----------
    name : str
    type : str
        In TOML words: ``number``, ``integer``, ``string``, ``boolean``, ``list of
        numbers``, ``table``, ``array of tables``.
    text : str
        What it means, one sentence.
    unit : str
        SI unit of its value(s), empty when it has none.
    default : str
        What stands when it is left out, or ``"required"``.
    allowed : str
        Its allowed values, in words.
    example : str
        One TOML line (or lines) setting it.
    alternative : bool
        One of a choice of keys (``period`` or ``rate_hz``): left out of the table's
        composed example, which has the other.
    """

    name: str
    type: str
    text: str
    unit: str = ""
    default: str = REQUIRED
    allowed: str = ""
    example: str = ""
    alternative: bool = False


@dataclass(frozen=True)
class Table:
    """A TOML table of a file and its keys.

    Attributes
    ----------
    name : str
        As written in the file: ``[experiment]``, ``[[connections]]``, ``(top level)``.
    text : str
        What it holds.
    keys : tuple of Key
    names : str
        For a table whose keys are names (a table of start values): what they are;
        such a table has no fixed keys.
    """

    name: str
    text: str
    keys: tuple = ()
    names: str = ""

    def example(self) -> str:
        """The table as TOML: its header and every key's example but alternatives."""
        head = "" if self.name.startswith("(") else \
            self.name.replace("NAME", "structure") + "\n"
        return head + "\n".join(k.example for k in self.keys
                                if k.example and not k.alternative
                                and not k.example.startswith("[")) + "\n"


_ANGLES = "rad, mrad, urad, deg, arcsec"
_METRICS = "peak_to_peak, rms_jitter, stability, rms, ape, mpe, rpe, pde"
_REF = "'instance.variable'"

SCENARIO = (
    Table("(top level)", "The tables of a scenario file.", (
        Key("experiment", "table", "Run times and the master's algorithm.",
            example="[experiment]"),
        Key("fmus", "table", "One [fmus.NAME] table per FMU instance.", example="[fmus.structure]"),
        Key("connections", "array of tables", "Output-to-input wiring.",
            default="[] (nothing wired)", example="[[connections]]"),
        Key("actions", "array of tables", "Values set at given times.",
            default="[] (none)", example="[[actions]]"),
        Key("record", "table", "What the results file holds.",
            default="nothing but time", example="[record]"),
    )),
    Table("[experiment]", "When the co-simulation starts and stops and how it steps.", (
        Key("start", "number", "Start time.", "s", "0", ">= 0", "start = 0.0"),
        Key("stop", "number", "Stop time.", "s", REQUIRED, "> start", "stop = 3.0"),
        Key("output_interval", "number", "Time between recorded rows.", "s", REQUIRED,
            "> 0, at most the run's length", "output_interval = 1e-3"),
        Key("algorithm", "string", "Order of the FMUs within a step.", "", '"gauss-seidel"',
            '"gauss-seidel" (along the feedthrough graph) or "jacobi" (each FMU sees the '
            "previous step's outputs)", 'algorithm = "gauss-seidel"'),
        Key("fmu_kind", "string", "Which build of the suite's FMUs runs.", "", '"native"',
            '"native" (C99) or "python" (pythonfmu twins in fmus/python/)',
            'fmu_kind = "native"'),
    )),
    Table("[fmus.NAME]", "One FMU instance; NAME is its name in references "
          "(letters, digits, _).", (
        Key("fmu", "string", "An FMU name looked up in --fmu-dir and fmus/, or a path "
            "to a .fmu file.", "", REQUIRED, "", 'fmu = "truss10_structure"'),
        Key("period", "number", "Communication step of the instance.", "s",
            "one of period or rate_hz is required", "> 0", "period = 1e-3"),
        Key("rate_hz", "number", "Communication rate, instead of period.", "Hz",
            "one of period or rate_hz is required", "> 0", "rate_hz = 1000.0",
            alternative=True),
        Key("parameters", "table", "Start values of parameters and inputs, by variable "
            "name (see [fmus.NAME.parameters]).", "", "{} (the FMU's own)", "",
            "parameters = { f_tip_x = 0.0 }"),
    )),
    Table("[fmus.NAME.parameters]", "Start values of the instance's parameters and "
          "inputs.", names="each key is a variable of the FMU (a parameter or an input), "
          "each value a number, boolean or string of its type, in its SI unit; "
          "e.g. gain = 1.0"),
    Table("[[connections]]", "One output wired to one input (an input takes one "
          "connection); the value passes as gain * output + offset.", (
        Key("from", "string", "The output.", "", REQUIRED, _REF,
            'from = "structure.strain_diag"'),
        Key("to", "string", "The input.", "", REQUIRED, _REF, 'to = "ctrl_diag.y1"'),
        Key("gain", "number", "Factor on the value.", "unit of 'to' per unit of 'from'",
            "1.0", "finite", "gain = 1.0"),
        Key("offset", "number", "Added to the value.", "unit of 'to'", "0.0", "finite",
            "offset = 0.0"),
    )),
    Table("[[actions]]", "Values set at a given time of the run.", (
        Key("time", "number", "When.", "s", REQUIRED, "within the run", "time = 1.0"),
        Key("set", "table", "The values set, by 'instance.variable'.", "", REQUIRED,
            "parameters and inputs of the FMUs",
            'set = { "ctrl_diag.gain" = 0.0 }'),
    )),
    Table("[record]", "What the results file holds besides time.", (
        Key("variables", "list of strings", "Variables recorded at every output "
            "interval.", "", "[] (time only)", f"{_REF} of numbers or booleans, each once",
            'variables = ["structure.los_tip_pitch"]'),
    )),
)

CAMPAIGN = (
    Table("(top level)", "The tables of a campaign file.", (
        Key("campaign", "table", "Name, base scenario, units and engine.", example="[campaign]"),
        Key("events", "array of tables", "Disturbance events, each run on its own.",
            default='one event "baseline" without overrides', example="[[events]]"),
        Key("configurations", "array of tables", "Configurations (e.g. isolation "
            "off/on), each run under every event.",
            default='one configuration "baseline"', example="[[configurations]]"),
        Key("sweeps", "array of tables", "Parameters swept over every event and "
            "configuration (see the sweep file).", default="[] (none)", example="[[sweeps]]"),
        Key("instruments", "array of tables", "Instruments and their line-of-sight "
            "axes.", example="[[instruments]]"),
        Key("metrics", "array of tables", "Jitter metrics of every axis.",
            default="peak_to_peak over a 1 s window", example="[[metrics]]"),
        Key("requirements", "array of tables", "Limits the budget is checked against.",
            default="[] (none)", example="[[requirements]]"),
        Key("wheel_sweeps", "array of tables", "Wheel speeds swept by the linear engine "
            "(see the sweep file).", default="[] (none)", example="[[wheel_sweeps]]"),
        Key("uncertainty", "table", "The Monte Carlo of the campaign (see the "
            "uncertainty file).", default="none", example="[uncertainty]"),
    )),
    Table("[campaign]", "The campaign as a whole; stop, output_interval and algorithm "
          "replace the base scenario's.", (
        Key("name", "string", "Names the output folder out/<name>.", "", '"campaign"',
            "", 'name = "truss10_quick"'),
        Key("scenario", "string or table", "The base scenario: a path to its TOML file "
            "(relative to the campaign file) or an inline table of the scenario layout.",
            "", REQUIRED, "", 'scenario = "../scenarios/truss10_campaign.toml"'),
        Key("unit", "string", "Unit of the jitter in the summary and of requirement "
            "values.", "", '"arcsec"', _ANGLES, 'unit = "arcsec"'),
        Key("skip", "number", "Transient dropped from the start of every record.", "s",
            "0.0", ">= 0 and < the run's length", "skip = 0.0"),
        Key("stop", "number", "Stop time of every case.", "s",
            "the base scenario's", "> start", "stop = 3.0"),
        Key("output_interval", "number", "Time between recorded rows.", "s",
            "the base scenario's", "> 0", "output_interval = 1e-3"),
        Key("algorithm", "string", "Master algorithm of every case.", "",
            "the base scenario's", '"gauss-seidel" or "jacobi"',
            'algorithm = "gauss-seidel"'),
        Key("engine", "string", "How the cases run.", "", '"cosim"',
            '"cosim" (co-simulation, the reference) or "linear" (the linear engine, '
            "milliseconds a case)", 'engine = "cosim"'),
        Key("verify", "integer", "With the linear engine, cases (the largest jitter) "
            "co-simulated to check it.", "", "2", ">= 0", "verify = 2"),
    )),
    Table("[[events]]", "A disturbance event: its overrides on the base scenario.", (
        Key("name", "string", "The event's name in tables and plots.", "", REQUIRED,
            'unique; not "RSS" (the total)', 'name = "diagonal 8.4 Hz"'),
        Key("overrides", "table", "Start values set for the event, by "
            "'instance.variable'.", "", "{}", "parameters and inputs of the FMUs, each "
            "value of the variable's type, SI units", 'overrides = { "excitation.amp1" = '
            "10.0 }"),
    )),
    Table("[[configurations]]", "A configuration: its overrides, run under every "
          "event.", (
        Key("name", "string", "The configuration's name.", "", REQUIRED, "unique",
            'name = "control on"'),
        Key("overrides", "table", "Start values set for it, by 'instance.variable'.", "",
            "{}", "as [[events]] overrides", 'overrides = { "ctrl_diag.gain" = 1.0 }'),
    )),
    Table("[[instruments]]", "An instrument: the recorded line-of-sight angles of its "
          "axes.", (
        Key("name", "string", "The instrument's name.", "", REQUIRED, "unique",
            'name = "tip"'),
        Key("axes", "table", "Axis name = recorded variable (a line-of-sight angle).",
            "rad", REQUIRED, f"{_REF} listed in the base scenario's [record] variables",
            'axes = { roll = "structure.los_tip_roll", pitch = "structure.los_tip_pitch" }'),
        Key("requirement", "number", "One limit for every axis, metric and window (a "
            "shorthand for [[requirements]]).", "[campaign] unit", "none", "> 0",
            "requirement = 5.0"),
    )),
    Table("[[metrics]]", "A jitter metric computed on every axis; each gives the "
          "largest value over the record.", (
        Key("kind", "string", "The metric.", "", REQUIRED, _METRICS + " (rms and ape "
            "take no window)", 'kind = "peak_to_peak"'),
        Key("windows", "list of numbers", "Windows (or lags) the metric is computed "
            "over.", "s", "[window] when window is given; required for a windowed kind",
            "> 0, at most the record after skip", "windows = [0.5]"),
        Key("window", "number", "One window, instead of windows.", "s", "none", "> 0",
            "window = 0.5", alternative=True),
    )),
    Table("[[requirements]]", "A limit on an instrument's jitter.", (
        Key("instrument", "string", "The instrument.", "", REQUIRED, "a name of "
            "[[instruments]]", 'instrument = "tip"'),
        Key("value", "number", "The limit.", "[campaign] unit", REQUIRED, "> 0",
            "value = 5.0"),
        Key("axis", "string", "The axis it applies to.", "", "every axis",
            "an axis of the instrument", 'axis = "pitch"'),
        Key("metric", "string", "The metric it applies to.", "", "every metric",
            _METRICS, 'metric = "peak_to_peak"'),
        Key("window", "number", "The window it applies to.", "s", "every window",
            "a window of a [[metrics]] entry", "window = 0.5"),
    )),
)

UNCERTAINTY = (
    Table("(top level)", "An uncertainty file holds one [uncertainty] table "
          "(jitterfmu campaign C --uncertainty U, analyze/design --uncertainty U); a "
          "campaign file may hold it too.", (
        Key("uncertainty", "table", "The uncertainty set and its sampling.",
            example="[uncertainty]"),
    )),
    Table("[uncertainty]", "The Monte Carlo: sample counts, seed, confidence levels.", (
        Key("samples", "integer", "Samples drawn (jitterfmu campaign --samples "
            "replaces it).", "", "200", ">= 1", "samples = 200"),
        Key("max_samples", "integer", "Extend the run from samples up to this count "
            "until its values converge.", "", "none (no extension)", ">= samples",
            "max_samples = 2000"),
        Key("seed", "integer", "Seed; sample s is drawn from default_rng([seed, s]).", "",
            "0", ">= 0", "seed = 1"),
        Key("confidence", "list of numbers", "Confidence levels of the stated "
            "values.", "", "[0.95, 0.9973]", "each in (0, 1)",
            "confidence = [0.95, 0.9973]"),
        Key("assurance", "number", "Probability that each level's upper bound lies "
            "above its true value.", "", "0.95", "in (0, 1)", "assurance = 0.95"),
        Key("parameters", "array of tables", "The uncertain inputs.", "", REQUIRED,
            "at least one", "[[uncertainty.parameters]]"),
        Key("engine", "string", "How the samples run.", "", '"linear"',
            '"linear" or "cosim" (no modal kinds)', 'engine = "linear"'),
    )),
    Table("[[uncertainty.parameters]]", "One uncertain input: a factor (or phases) "
          "drawn from a distribution.", (
        Key("name", "string", "Its name in the results.", "", "its kind", "unique",
            'name = "amplitudes"'),
        Key("kind", "string", "What it scales.", "", REQUIRED,
            "modal_frequency (factor on the modal frequencies), modal_damping (factor on "
            "the modal damping ratios), amplitude (factor on a source's wrench), phase "
            "(random phases of a source), frequency (factor on a source's frequencies), "
            "gain (factor on a controller's gain)", 'kind = "amplitude"'),
        Key("distribution", "string", "The distribution of the factor.", "",
            "required but for kind phase", "uniform (low, high), normal (mean, std), "
            "lognormal (median, sigma)", 'distribution = "uniform"'),
        Key("low", "number", "Lower end (uniform), or truncation.", "factor",
            "none (-inf)", "< high; >= 0 for modal kinds, > 0 for frequency",
            "low = 0.8"),
        Key("high", "number", "Upper end (uniform), or truncation.", "factor",
            "none (+inf)", "> low", "high = 1.2"),
        Key("mean", "number", "Mean (normal).", "factor", "0.0", "", "mean = 1.0",
            alternative=True),
        Key("std", "number", "Standard deviation (normal).", "factor", "0.0", "> 0",
            "std = 0.05", alternative=True),
        Key("median", "number", "Median (lognormal).", "factor", "1.0", "> 0",
            "median = 1.0", alternative=True),
        Key("sigma", "number", "Standard deviation of the logarithm (lognormal).", "",
            "0.0", "> 0", "sigma = 0.1", alternative=True),
        Key("instances", "string or list of strings", "Sources (amplitude, phase, "
            "frequency) or controllers (gain) it applies to.", "",
            "required for those kinds", '"all" or instances of the base scenario',
            'instances = "all"'),
        Key("per_mode", "boolean", "Modal kinds: one draw per mode, else one factor for "
            "all.", "", "false", "", "per_mode = false"),
        Key("band", "list of numbers", "Modal kinds: modes in [low, high].", "Hz",
            "[0, inf] (every mode)", "low < high", "band = [0.0, 200.0]"),
    )),
)

SWEEP = (
    Table("[[sweeps]]", "A campaign file's parameter sweep: every event and "
          "configuration runs at each value.", (
        Key("parameter", "string", "The swept start value.", "", REQUIRED,
            f"{_REF}: a parameter or input", 'parameter = "ctrl_iso1.gain"'),
        Key("values", "list", "Its values, each of the variable's type.",
            "the variable's SI unit", REQUIRED, "non-empty", "values = [0.5, 1.0, 2.0]"),
    )),
    Table("[[wheel_sweeps]]", "A campaign file's wheel-speed sweep on the linear "
          "engine: the jitter of a wheel-imbalance source over its speed range.", (
        Key("name", "string", "The sweep's name.", "", "its instance", "",
            'name = "RWA speed"'),
        Key("instance", "string", "The wheel-imbalance source swept.", "", REQUIRED,
            "an instance of the base scenario", 'instance = "dist_rwa"'),
        Key("overrides", "table", "Start values set with every configuration's (e.g. "
            "the wheel's preset).", "", "{}", "as [[events]] overrides",
            'overrides = { "dist_rwa.preset" = "rwa" }'),
        Key("rpm", "list of numbers", "Speed range [low, high].", "rpm", "[0.0, 6000.0]",
            "0 <= low < high", "rpm = [0.0, 6000.0]"),
        Key("points", "integer", "Speeds, evenly spaced, ends included.", "", "500",
            ">= 2", "points = 500"),
        Key("open", "list of strings", "Instances taken out of the loop (e.g. a slow "
            "ACS).", "", "[] (none)", "instances of the base scenario",
            'open = ["acs"]'),
    )),
)

#: File kind -> (what it is, its tables).
FILES = {
    "scenario": ("A scenario file (jitterfmu run, analyze, campaign's base scenario): "
                 "FMU instances, their wiring, actions and what is recorded.", SCENARIO),
    "campaign": ("A campaign file (jitterfmu campaign): events x configurations x "
                 "sweeps on a base scenario, instruments, metrics and requirements.",
                 CAMPAIGN),
    "uncertainty": ("An uncertainty file: the [uncertainty] table of a Monte Carlo or a "
                    "robust analysis.", UNCERTAINTY),
    "sweep": ("The sweep tables of a campaign file ([[sweeps]], [[wheel_sweeps]]); a "
              "sweep file is a campaign file whose work is its sweeps "
              "(campaigns/eos_rwa_sweep.toml).", SWEEP),
}


def table(name: str) -> Table:
    """The table written ``name`` in a file (``"[experiment]"``, ``"[[metrics]]"``).

    Parameters
    ----------
    name : str
        As in :attr:`Table.name`; ``"scenario"``/``"campaign"`` for the top level.
    """
    if name in FILES:
        return FILES[name][1][0]
    for _, tables in FILES.values():
        for t in tables:
            if t.name == name:
                return t
    raise KeyError(f"no table {name!r} in the key reference")


def keys(name: str) -> tuple:
    """The valid keys of the table written ``name`` (see :func:`table`), in order.

    Parameters
    ----------
    name : str
        The table.
    """
    return tuple(k.name for k in table(name).keys)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ") or "-"


def markdown(kinds=None) -> str:
    """The key reference as Markdown (``docs/reference.md`` is this for every kind).

    Parameters
    ----------
    kinds : sequence of str, optional
        File kinds of :data:`FILES` (default: all).
    """
    out = []
    if kinds is None:
        kinds = list(FILES)
        out += ["# Key reference", "",
                "Every key of the files a user writes, generated from the parsers' own "
                "schema (`orchestrator/schema.py`; `jitterfmu keys KIND` prints one kind). "
                "A key not listed here is refused with the closest valid key. Values are "
                "in SI units unless the unit column says otherwise.", ""]
    for kind in kinds:
        what, tables = FILES[kind]
        out += [f"## {kind.capitalize()} file", "", what, ""]
        for t in tables:
            out += [f"### `{t.name}`", "", t.text, ""]
            if t.names:
                out += [f"Keys: {t.names}.", ""]
                continue
            out += ["| key | meaning | type | unit | default | allowed | example |",
                    "|---|---|---|---|---|---|---|"]
            for k in t.keys:
                ex = f"`{k.example}`" if k.example else "-"
                out.append(f"| `{k.name}` | {_cell(k.text)} | {_cell(k.type)} | "
                           f"{_cell(k.unit)} | {_cell(k.default)} | {_cell(k.allowed)} | "
                           f"{ex} |")
            out.append("")
            if not t.name.startswith("("):
                out += ["```toml", t.example().rstrip("\n"), "```", ""]
    return "\n".join(out)


def text(kinds=None) -> str:
    """The key reference as plain text for a terminal (``jitterfmu keys``).

    Parameters
    ----------
    kinds : sequence of str, optional
        File kinds of :data:`FILES` (default: all).
    """
    out = []
    for kind in kinds or list(FILES):
        what, tables = FILES[kind]
        out += [f"{kind.upper()} FILE: {what}", ""]
        for t in tables:
            out.append(f"{t.name}  {t.text}")
            if t.names:
                out.append(f"  keys: {t.names}")
            for k in t.keys:
                unit = f", {k.unit}" if k.unit else ""
                allowed = f"; {k.allowed}" if k.allowed else ""
                out.append(f"  {k.name:<16}{k.type}{unit}; default: {k.default}{allowed}")
                out.append(f"  {'':<16}{k.text}" + (f"  e.g. {k.example}" if k.example
                                                    else ""))
            out.append("")
    return "\n".join(out)
