"""Campaigns: many scenario runs (events × configurations × sweeps), their jitter and budget.

A campaign is a base scenario plus a matrix of cases.  Every case applies parameter
overrides to the base scenario — one disturbance event (each event runs alone), one
configuration (e.g. isolation off / on) and one point of the parameter sweeps — and is run
by a *runner*, any callable ``runner(scenario_dict, out_dir)`` that writes
``out_dir/results.parquet`` and returns its table (a :class:`~orchestrator.results.RunResult`)
or the file's path.
The default runner is the co-simulation master (:class:`MasterRunner`); tests and scripts may
pass any picklable callable.  Each finished case's recorded line-of-sight (LOS) angles are
turned into jitter metrics (:mod:`orchestrator.metrics`), and the campaign's summary holds
one row per case, instrument, axis, metric and window plus the RSS over events of every
configuration and sweep point, against the requirements.

Campaign file (TOML), e.g. ``campaigns/truss10_quick.toml`` (abridged; every path is
relative to the campaign file)::

    [campaign]
    name = "truss10_quick"
    scenario = "../scenarios/truss10_campaign.toml"   # the base scenario
    unit = "arcsec"                          # unit of the summary, requirements and report
    skip = 0.0                               # s of transient dropped from every record
    stop = 3.0                               # optional experiment overrides of the base
    output_interval = 1e-3

    [[events]]                               # each case turns on exactly one event
    name = "diagonal 8.4 Hz"
    overrides = { "excitation.amp1" = 10.0 }

    [[configurations]]                       # every event runs in every configuration
    name = "control off"
    overrides = { "ctrl_diag.gain" = 0.0, "ctrl_long.gain" = 0.0 }

    [[sweeps]]                               # optional, cartesian product of all sweeps
    parameter = "piezo_diag.bandwidth"
    values = [1000.0, 2000.0]

    [[instruments]]                          # recorded LOS angles (rad) per axis
    name = "tip"
    axes = { pitch = "structure.los_tip_pitch", yaw = "structure.los_tip_yaw" }

    [[metrics]]                              # kind and windows (s); stability: lags (s)
    kind = "peak_to_peak"                    # peak_to_peak | rms_jitter | stability | rms
    windows = [0.5]

    [[requirements]]                         # in `unit`; axis and window optional
    instrument = "tip"
    metric = "peak_to_peak"
    window = 0.5
    value = 5.0

Output folder::

    DIR/campaign.json          the expanded campaign (cases, keys, swept parameters' units)
    DIR/cases/KEY/case.json    definition, status ("ok" or "failed"), error, timings
    DIR/cases/KEY/results.parquet, metrics.parquet   (successful cases)
    DIR/cases.parquet, cases.csv       one row per case with its status and error
    DIR/summary.parquet        the jitter table, every row (see :func:`summarize`)
    DIR/summary.csv            its case rows; a swept parameter is a numeric column
    DIR/budget.csv             its RSS rows: the budget against the requirements
    with --format csv / mat    cases/KEY/results.csv or .mat (units), campaign.mat
                               (summary, budget, cases, Monte Carlo samples; export.py)

Resuming
--------
A case is keyed by the SHA-256 of its definition (scenario after overrides, instruments,
metrics, skip) and of the runner's fingerprint of the FMUs it uses; the key, and so the
folder's name, is the case's label beside 16 digits of that digest
(``ceres_scan_isolation_off-3fa2c1d09be47a15``).  A case runs in a
temporary folder which is renamed to ``cases/KEY`` (``os.replace``) only when complete, so
a killed campaign loses only the cases in flight; running the campaign again skips every
case whose folder says "ok" and retries failed ones.  A folder is trusted only when it is
a real folder (not a symbolic link) whose ``case.json`` holds the case's own key and
scenario and whose files have the recorded sizes and SHA-256; any other (a copy of
another case's folder, a link, a replaced file) runs again, and ``jitterfmu campaign``
says so in one line.  A plain file where a case folder belongs fails that case only.
Every ``instance.variable`` the campaign sets is checked against its FMU before any case
runs.  In this process or a local pool, SIGTERM or SIGINT stops the campaign after
keeping the finished cases (:class:`CampaignInterrupted`, exit status 128 + the signal).

Engines
-------
``engine = "cosim"`` (the default) co-simulates every case with the master.  ``engine =
"linear"`` (``jitterfmu campaign C.toml --engine linear``) computes the same recorded
signals from the same discretised models the FMUs step, closed once per configuration
(:mod:`orchestrator.analysis.fast`), in milliseconds a case; a case that holds what the
linear model leaves out (hysteresis, noise, an input-driven wheel, a third-party FMU) or
whose record reaches a rail or limit fails with one sentence saying so.  ``verify = N``
(``--verify N``) then co-simulates the N cases with the largest jitter and writes the
largest difference per instrument and axis to ``verify.json`` (and the report).

Parallelism
-----------
``workers=0`` runs the cases one after another in this process; ``workers >= 1`` uses a
process pool (forkserver on Linux, spawn elsewhere) with at most ``workers`` cases in
flight; ``scheduler="tcp://..."`` (or a ``distributed.Client``) submits them to an existing
Dask cluster whose workers must see ``DIR`` (shared file system).  Every mode computes the
same numbers: each case is a pure function of its definition.

Modules, in pipeline order
--------------------------
:mod:`~orchestrator.campaign.spec`
    the campaign file, parsed and checked table by table;
:mod:`~orchestrator.campaign.cases`
    the cases: the base scenario with each event, configuration and sweep point, keyed;
:mod:`~orchestrator.campaign.runner`
    one case: run, jitter metrics from the table in memory, its folder published;
:mod:`~orchestrator.campaign.engine`
    all cases: serially, in a process pool or on Dask; folder lock, resume;
:mod:`~orchestrator.campaign.linear`
    the linear engine as a runner (``engine = "linear"``), and ``--verify N``: the cases
    with the largest jitter co-simulated and compared;
:mod:`~orchestrator.campaign.wheel`
    ``[[wheel_sweeps]]``: steady-state jitter over a wheel's speed range, per
    configuration, on the linear engine;
:mod:`~orchestrator.campaign.montecarlo`
    ``[uncertainty]``: the budget as a distribution over uncertain modes, gains and
    sources, with ECSS statistics and a sensitivity ranking, on the linear engine;
:mod:`~orchestrator.campaign.summary`
    the summary table: jitter, RSS over the events, margins;
:mod:`~orchestrator.campaign.store`
    the case folders on disk: status, file records, atomic writes.
"""


from .cases import Campaign, Case, campaign_from_dict, keyed, load_campaign
from .engine import CampaignResult, run_campaign
from .linear import LinearRunner, verify_campaign
from .montecarlo import check_uncertain_inputs, run_uncertainty
from .runner import CampaignInterrupted, MasterRunner, case_metrics, execute_case
from .spec import ANGLE_UNITS, ENGINES, METRIC_KINDS, RSS_EVENT, CampaignError
from .store import slug
from .summary import SUMMARY_SCHEMA, summarize, write_summary
from .wheel import run_wheel_sweeps

__all__ = [
    "ANGLE_UNITS",
    "ENGINES",
    "METRIC_KINDS",
    "Campaign",
    "CampaignError",
    "CampaignInterrupted",
    "CampaignResult",
    "Case",
    "LinearRunner",
    "MasterRunner",
    "RSS_EVENT",
    "SUMMARY_SCHEMA",
    "campaign_from_dict",
    "case_metrics",
    "check_uncertain_inputs",
    "execute_case",
    "keyed",
    "load_campaign",
    "run_campaign",
    "run_uncertainty",
    "run_wheel_sweeps",
    "slug",
    "summarize",
    "verify_campaign",
    "write_summary",
]
