"""Running a campaign's cases: in this process, in a process pool or on a Dask cluster.

The campaign folder is locked for the run; cases whose folders are verified finished are
skipped (resume), the others run with at most ``workers`` in flight, and a case whose
worker died is recorded as failed.  Pool workers exit when the campaign process dies.
In this process or a local pool, SIGTERM or SIGINT stops the campaign: the finished
cases are kept, those in flight are dropped (the pool's workers are ended), and
:class:`CampaignInterrupted` says so.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import shutil
import signal
import threading
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path

from ..progress import ProgressBar
from .cases import Campaign, Case, keyed
from .runner import CampaignInterrupted, MasterRunner, execute_case, one_sentence
from .spec import CampaignError
from .store import case_doubt, record_lost, write_json
from .summary import write_summary

_LOCK_FILE = ".jitterfmu.lock"
_WORKER_DIED = "a worker process died while this case ran"


@dataclass(frozen=True)
class CampaignResult:
    """What a campaign run did.

    Attributes
    ----------
    out_dir : Path
    n_cases, n_run, n_skipped, n_failed : int
        All cases; run now; skipped because already finished; failed (now).
    summary : Path
        ``summary.parquet``.
    failures : dict of str to str
        Case label to one-sentence error.
    rerun : dict of str to str
        Case label to why its folder was not trusted (a copied or linked folder of
        another case, files that are not the recorded ones); those cases ran again.
    """

    out_dir: Path
    n_cases: int
    n_run: int
    n_skipped: int
    n_failed: int
    summary: Path
    failures: dict
    rerun: dict = field(default_factory=dict)

    def __iter__(self):
        return iter((self.n_failed, self.summary))


def run_campaign(
    campaign: Campaign,
    out_dir,
    runner: Callable | None = None,
    *,
    workers: int | None = None,
    scheduler=None,
    progress: bool | None = None,
) -> CampaignResult:
    """Run every unfinished case of a campaign and write the summary.

    Parameters
    ----------
    campaign : Campaign
        From :func:`~orchestrator.campaign.load_campaign` or
        :func:`~orchestrator.campaign.campaign_from_dict`.
    out_dir : path-like
        Output folder (created; reused to resume).
    runner : callable, optional
        ``runner(scenario_dict, out_dir)`` returning a RunResult or the path of
        ``results.parquet``; picklable for ``workers >= 1`` and Dask.  Default:
        :class:`~orchestrator.campaign.MasterRunner`.  If it has a
        ``fingerprint(scenario_dict) -> str`` method, that enters the case keys.
    workers : int, optional
        0 runs the cases in this process; N >= 1 uses N worker processes.  Default: the
        number of CPUs.  Ignored when ``scheduler`` is given, and with the linear
        engine (its cases run in this process, on one compiled loop per configuration).
    scheduler : str or distributed.Client, optional
        Address of a Dask scheduler (or a client) to run the cases on.
    progress : bool, optional
        Draw a progress bar on stderr; default: only when stderr is a terminal.

    Returns
    -------
    CampaignResult
        Unpacks as ``n_failed, summary_path``.

    Raises
    ------
    CampaignError
        Before any case runs, when an override or swept parameter names a variable its
        FMU does not have or cannot set (runners with ``override_problem``), or when
        ``out_dir`` or its ``cases`` is a file.
    CampaignInterrupted
        On SIGTERM or SIGINT (not with a Dask scheduler): the finished cases are kept
        and their summary written; the message says what was kept and how to resume.
    """
    out = Path(out_dir)
    cases_dir = out / "cases"
    if runner is None and campaign.engine == "linear":
        from .linear import LinearRunner
        runner = LinearRunner(campaign.scenario_dir)
    runner = runner or MasterRunner(campaign.scenario_dir)
    if getattr(runner, "engine", "cosim") == "linear":
        # one compiled loop per configuration, kept in this process
        workers, scheduler = 0, None
    _check_overrides(campaign, runner)
    for folder in (out, cases_dir):
        if folder.exists() and not folder.is_dir():
            raise CampaignError(f"{str(folder)!r} is a file, not a campaign folder; move it "
                                "away or choose another --out")
    cases_dir.mkdir(parents=True, exist_ok=True)
    with _folder_lock(out):
        for stale in cases_dir.glob(".tmp-*"):  # left by a killed run
            shutil.rmtree(stale, ignore_errors=True)
        campaign = keyed(campaign, runner)
        write_json(out / "campaign.json", {
            "name": campaign.name, "unit": campaign.unit, "skip": campaign.skip,
            "engine": getattr(runner, "engine", "cosim"),
            "instruments": campaign.instruments, "metrics": campaign.metrics,
            "requirements": campaign.requirements,
            "sweep_units": _sweep_units(campaign, runner),
            "cases": [{"key": c.key, "label": c.label, "event": c.event,
                       "configuration": c.configuration, "sweep": c.sweep} for c in campaign.cases],
        })
        doubts = {case.key: case_doubt(cases_dir, case) for case in campaign.cases}
        todo = [case for case in campaign.cases if doubts[case.key] is not None]
        rerun = {case.label: doubts[case.key] for case in todo if doubts[case.key]}
        skipped = len(campaign.cases) - len(todo)
        bar = ProgressBar(len(campaign.cases), "campaign", "case", enabled=progress)
        for _ in range(skipped):
            bar.update("ok")
        failures = {}

        finished = []

        def on_done(case, status):
            finished.append(case.key)
            if status["status"] == "failed":
                failures[case.label] = status["error"]
                if status.get("unpublished"):  # the case never wrote its folder
                    record_lost(cases_dir, case, status["error"])
            bar.update(status["status"])

        args = (runner, cases_dir, campaign.instruments, campaign.metrics, campaign.skip)
        workers = (os.cpu_count() or 1) if workers is None else int(workers)
        try:
            if scheduler is not None:
                _run_dask(todo, args, scheduler, on_done)
            elif getattr(runner, "engine", "cosim") == "linear" and len(todo) > 1:
                with _stop_on_signals():
                    _run_threads(todo, args, on_done)
            elif workers <= 0:
                with _stop_on_signals():
                    for case in todo:
                        on_done(case, execute_case(case, *args))
            else:
                with _stop_on_signals():
                    _run_local(todo, args, workers, on_done)
        except (CampaignInterrupted, KeyboardInterrupt) as exc:
            bar.close()
            signum = getattr(exc, "signum", signal.SIGINT)
            for stale in cases_dir.glob(".tmp-*"):  # the cases that were in flight
                shutil.rmtree(stale, ignore_errors=True)
            write_summary(campaign, out)
            kept = skipped + len(finished) - len(failures)
            raise CampaignInterrupted(signum, (
                f"campaign {campaign.name!r} stopped by {signal.Signals(signum).name}: kept "
                f"{kept} finished case(s) in {str(cases_dir)!r}, {len(todo) - len(finished)} "
                "not run; run the same command again to resume")) from None
        finally:
            bar.close()
        summary_path = write_summary(campaign, out)
        return CampaignResult(out, len(campaign.cases), len(todo), skipped, len(failures),
                              summary_path, failures, rerun)


def _check_overrides(campaign: Campaign, runner) -> None:
    """Every variable the campaign sets must be settable in its FMU, every value it
    takes one of its type, and every instrument axis a recorded variable of its FMU
    (checked before any case runs).  A campaign of wheel sweeps alone is checked on
    its first sweep's scenario, where an instrument need not be recorded."""
    if not (campaign.cases or campaign.wheel_sweeps):
        return
    # cases differ in parameter values only
    base = (campaign.cases[0].scenario if campaign.cases
            else campaign.wheel_sweeps[0]["scenario"])
    problem = getattr(runner, "override_problem", None)
    for where, ref, values in campaign.overrides if problem else ():
        why = problem(base, ref, values)
        if why:
            raise CampaignError(f"{campaign.source}: {where}: {why}")
    output = getattr(runner, "output_problem", None)
    for name, axes in campaign.instruments.items() if output else ():
        for axis, ref in axes.items():
            why = output(base, ref, recorded=bool(campaign.cases))
            if why:
                raise CampaignError(f"{campaign.source}: instrument {name!r} axis {axis!r}: "
                                    f"{why}")


def _sweep_units(campaign: Campaign, runner) -> dict:
    """``{instance.variable: unit}`` of every swept parameter whose FMU declares a unit
    (runners with ``unit_of``), for the report's axes and legends."""
    unit_of = getattr(runner, "unit_of", None)
    if unit_of is None or not campaign.cases:
        return {}
    base = campaign.cases[0].scenario
    refs = dict.fromkeys(ref for where, ref, _ in campaign.overrides
                         if where.startswith("sweep "))
    units = {ref: unit_of(base, ref) for ref in refs}
    return {ref: u for ref, u in units.items() if u}


@contextlib.contextmanager
def _stop_on_signals():
    """SIGTERM and SIGINT raise :class:`CampaignInterrupted` (main thread only).

    The master installs its own handlers for the length of a run (it ends the run
    between steps); this handler covers the campaign's own code between runs and
    runners without such a guard.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handle(signum, frame):
        raise CampaignInterrupted(signum)

    previous = {sig: signal.signal(sig, handle) for sig in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _run_threads(todo, args, on_done):
    """The linear engine's cases in threads of this process, one per core: they share
    its compiled loops (a configuration is closed once: the runner's lock holds the
    others back while it is), and their products and the window kernel release the GIL;
    one BLAS thread each, and the process's own count back afterwards (a worker's leaks
    into the process: :func:`orchestrator.analysis._threads.blas_threads_kept`)."""
    from concurrent.futures import ThreadPoolExecutor, as_completed

    from ..analysis._threads import blas_threads_kept, one_blas_thread

    with blas_threads_kept():
        pool = ThreadPoolExecutor(min(len(todo), os.cpu_count() or 1),
                                  initializer=one_blas_thread)
        futs = {pool.submit(execute_case, case, *args): case for case in _loops_first(todo)}
        reported = set()
        try:
            for fut in as_completed(futs):
                reported.add(fut)
                on_done(futs[fut], fut.result())
        except BaseException:
            # interrupted: the cases not started are dropped; those running finish (a
            # linear case takes milliseconds) and are counted, before the caller tidies
            # the folder
            pool.shutdown(wait=True, cancel_futures=True)
            for fut, case in futs.items():
                if fut not in reported and not fut.cancelled():
                    on_done(case, fut.result())
            raise
        finally:
            pool.shutdown(wait=False)


def _loops_first(todo) -> list:
    """The cases in the order threads take them: one case of every configuration first
    (each builds its loop, at once on several threads), then the rest configuration by
    configuration, so that a thread finds cases whose loop is built while another loop
    is still building, rather than waiting for it."""
    groups = {}
    for case in todo:
        groups.setdefault(case.configuration, []).append(case)
    return [g[0] for g in groups.values()] + [c for g in groups.values() for c in g[1:]]


def _run_local(todo, args, workers, on_done):
    """Process pool with at most ``workers`` cases in flight; survives dead workers."""
    queue = list(todo)
    while queue:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=_pool_context(),
                                   initializer=_die_with_parent, initargs=(os.getpid(),))
        inflight = {}
        broken = False
        try:
            while queue or inflight:
                while queue and len(inflight) < workers and not broken:
                    case = queue.pop(0)
                    inflight[pool.submit(execute_case, case, *args)] = case
                if not inflight:
                    break
                done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                for fut in done:
                    case = inflight.pop(fut)
                    try:
                        on_done(case, fut.result())
                    except BrokenProcessPool:
                        broken = True
                        on_done(case, _lost(case, _WORKER_DIED))
                if broken:
                    for fut, case in inflight.items():
                        on_done(case, _lost(case, _WORKER_DIED))
                    inflight.clear()
                    break
        except BaseException:   # interrupted: end the cases in flight, not wait for them
            broken = True
            # the executor has no public way to end its workers; its process table does
            procs = list(getattr(pool, "_processes", {}).values())
            for proc in procs:
                proc.terminate()
            for proc in procs:
                proc.join(timeout=10)
            raise
        finally:
            pool.shutdown(wait=not broken, cancel_futures=True)


def _run_dask(todo, args, scheduler, on_done):
    # distributed is an optional extra ("cluster"), imported only when a scheduler is given
    try:
        # deferred: optional dependency (the cluster extra)
        from distributed import Client, as_completed
    except ImportError:
        raise CampaignError(
            "a Dask scheduler was given but the 'distributed' package is not installed "
            "(install the 'cluster' extra)"
        ) from None
    own = not hasattr(scheduler, "submit")
    client = Client(scheduler) if own else scheduler
    try:
        futs = {client.submit(execute_case, case, *args, key=f"case-{case.key}", pure=False): case
                for case in todo}
        for fut in as_completed(futs):
            case = futs[fut]
            try:
                on_done(case, fut.result())
            except Exception as exc:  # the worker died or the task was lost
                on_done(case, _lost(case, one_sentence(exc)))
    finally:
        if own:
            client.close()


def _lost(case: Case, why: str) -> dict:
    return {"key": case.key, "status": "failed", "error": why, "seconds": float("nan"),
            "unpublished": True}


def _pool_context():
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


class _folder_lock:
    """Exclusive lock on a campaign folder for the life of a campaign run.

    A second campaign (or a run) into the same folder fails at once instead of deleting
    the other's in-progress cases; the lock goes with the process, so a killed
    campaign leaves nothing to clean up.
    """

    def __init__(self, folder: Path):
        self.path = Path(folder) / _LOCK_FILE

    def __enter__(self):
        import fcntl  # POSIX only: imported where the lock is taken

        self.file = open(self.path, "a+")
        try:
            fcntl.flock(self.file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self.file.close()
            raise CampaignError(f"campaign folder {str(self.path.parent)!r} is in use by "
                                "another campaign or run; wait for it or choose another "
                                "--out") from None
        return self

    def __exit__(self, *exc):
        self.file.close()   # releases the lock
        return False


def _die_with_parent(parent_pid: int, period: float = 1.0) -> None:
    """Pool worker initialiser: exit when the campaign process is gone.

    A killed campaign would otherwise leave its workers running cases and writing into
    its folder.  A daemon thread checks every ``period`` seconds that ``parent_pid``
    still exists (the pool's own parent may be a fork server, so the check names the
    campaign process itself).
    """
    def watch():
        while True:
            time.sleep(period)
            if not _alive(parent_pid):
                os._exit(1)

    threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


def _alive(pid: int) -> bool:
    """Whether process ``pid`` still runs: a zombie (dead, not yet reaped) does not.

    ``os.kill(pid, 0)`` succeeds on a zombie, so on Linux the state letter of
    ``/proc/PID/stat`` decides (``Z`` zombie, ``X`` dead); elsewhere the signal check.
    """
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:   # another user's process: it exists
        pass
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            stat = f.read()
    except FileNotFoundError:
        return not os.path.isdir("/proc/self")    # gone, where /proc exists
    except OSError:
        return True
    # "pid (command) S ...": the command may hold spaces and parentheses
    return stat.rpartition(b")")[2].split()[:1] not in ([b"Z"], [b"X"])
