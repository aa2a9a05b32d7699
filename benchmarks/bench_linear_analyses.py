"""Weekly analyses on the EOS budget: RWA wheel-speed sweep and Monte Carlo, side by side.

Run::

    .venv/bin/python benchmarks/bench_linear_analyses.py [--samples 20] [--core-samples 6]
        [--repeat 3] [--modes 70,140,280,500] [--no-sweep] [--verdicts 1000] [--json FILE]

* **RWA sweep**: 500 wheel speeds 0-6000 rpm, all 5 instruments x 3 axes, isolation off
  and on (``campaigns/eos_rwa_sweep.toml``), steady state on the linear engine; beside it
  the cost of the alternative, one co-simulated case per speed (the budget's RWA case,
  8 s at 1 kHz, timed here) times 500.  ``--repeat`` sweeps from scratch, each on a
  fresh runner: the median is printed, and the range.
* **Monte Carlo**: the budget (12 events x 2 configurations) under the shipped
  ``campaigns/eos_uncertainty.toml`` (modal frequencies +-5 % and damping x0.5-2, every
  mode on its own, amplitudes +-20 %, every source on its own).  The cost of a sample is
  timed on one core in this process (``--core-samples``, after a first one builds the
  run types), and 1000 samples on ``--workers`` cores are that times 1000 over the
  cores; beside it 1000 x 24 co-simulated cases at the measured case cost.  Whole runs
  of a quarter of ``--samples`` and of ``--samples`` on ``--workers`` processes give
  the command's own rate and the peak memory with both counts: it does not grow with
  the samples.
* **Structured against dense** (``benchmarks/_structured.py``): the same samples on
  both engines, one core, interleaved sample by sample (a busy machine slows both
  alike): seconds a sample each, their largest metric difference and whether the
  statuses agree; the structured floor (the flops of a structured sample, in its own
  shapes, over this machine's one-thread square dgemm rate); and both engines with the
  EOS structure reduced to each of ``--modes`` (memory states, the slope of the
  per-sample cost against the memory state, the bytes of the structured forms, each
  configuration's poles and the slope without them): the structured samples of every
  size in rounds, ``--core-samples`` of a size in a row after a warm one (the first
  round warms), so that the slope does not follow a drifting load; then the dense.
* **The exact floor of a sample** (``--no-floor`` leaves it out): the products an exact
  engine cannot leave out, on the nominal loops the samples perturb (their memory
  states, live rows and driven channels): the free responses of the 24 records after the
  campaign's skip (the lines of sight before it are not needed), the row and column
  Krylov products of every run type (in the doubling steps the engine uses),
  its ``M^L``, the state recursion over the runs (the start states the free responses
  need) with the input side of each record's channels, and the eigenvalues of the
  super-period map.  Printed as flops over this machine's one-thread square dgemm rate
  (a lower bound: no product runs faster than that), and as the same products timed in
  their own shapes on one thread; beside it, the measured cost of a sample.  With it,
  what rules out the cheaper exact formulations (:func:`formulations`): the density of
  the loops' tick maps, their eigenvalues at 1 and eigenvector condition, and the band
  of the static Ritz block's modes.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _measure import best_of, blas_choice, peak_rss_mb  # noqa: E402
import _structured  # noqa: E402

import numpy as np  # noqa: E402

from orchestrator.analysis._threads import one_blas_thread  # noqa: E402
from orchestrator.analysis.fastparts import _doubling  # noqa: E402
from orchestrator.analysis.steady import balance  # noqa: E402
from orchestrator.analysis.uncertainty import draw  # noqa: E402
from orchestrator.campaign import (LinearRunner, MasterRunner, load_campaign,  # noqa: E402
                                   run_uncertainty, run_wheel_sweeps)
from orchestrator.campaign import montecarlo as mcm  # noqa: E402
from orchestrator.experiments import eos  # noqa: E402


def _products(camp, runner) -> tuple:
    """The products an exact sample cannot leave out, on the nominal loops.

    Parameters
    ----------
    camp : Campaign
        The Monte Carlo campaign (its cases, lines and ``[uncertainty]``).
    runner : LinearRunner
        Its runner.

    Returns
    -------
    (gemms, eigs, rows)
        ``gemms`` a list of ``(count, m, k, n)``: ``count`` products of an ``(m, k)`` by
        a ``(k, n)`` matrix; ``eigs`` the balanced super-period maps whose eigenvalues a
        sample needs (the nominal ones); ``rows`` a line per configuration naming its sizes.
    """
    ctx = mcm._setup(camp, runner)
    items = camp.uncertainty["parameters"]
    lin0, structs, _ = ctx["base"][ctx["configs"][0]]
    draws = draw(items, 1, camp.uncertainty["seed"],
                 lin0.blocks[structs[0]].model.frequencies_hz)
    gemms, eigs, rows = [], [], []
    for cf in ctx["configs"]:
        lin, _, fr = ctx["base"][cf]
        s = fr.n_memory
        Ws = [mcm._sample_input(runner, fr, *ctx["inputs"][(cf, ev)], draws, items, 0)[0]
              for ev in ctx["events"]]
        E, K = len(Ws), Ws[0].shape[0]
        # the lines of sight a campaign's skip discards are not needed (their limits are:
        # bounded from the states, which the recursion gives)
        kept = (K - mcm.first_tick(camp, lin)) / K
        drives = [np.flatnonzero(np.any(W != 0, axis=0)) for W in Ws]
        k = np.unique(np.concatenate(drives)).size
        k_sum = sum(d.size for d in drives)       # each record's own channels
        n_los = len(fr._computed)
        runs = {}
        for sig, L in fr._runs:
            runs[(sig, L)] = runs.get((sig, L), 0) + 1
        n_periods = K / fr.P
        lives = []
        for (sig, L), per_period in runs.items():
            t = fr._type(sig, L)
            lives.append(t.live.size)
            n_u = max(1, round(per_period * n_periods))
            if L > 1:   # the Krylov products by doubling, as the engine does them
                for lo, hi in _doubling(L):                  # rows q in [lo, hi)
                    gemms += [(1, (hi - lo) * t.live.size, s, s),   # row Krylov C M^q
                              (1, s, s, (hi - lo) * k)]             # column Krylov M^q N
                gemms.append((L.bit_length() + bin(L).count("1") - 2, s, s, s))   # M^L
            gemms.append((1, E * max(1, round(n_u * kept)), s, L * n_los))   # free
            # the state recursion: a run's start states from the one before, for every
            # record (what the free responses start from), and the input side of each
            # record's own channels over its runs
            gemms += [(n_u, s, s, E), (1, n_u, L * k_sum, s)]
        eigs.append(balance(fr.period_map())[0])
        rows.append(f"{cf}: memory state {s}, live rows {'/'.join(map(str, lives))}, "
                    f"{k} driven channels, {E} records of {K} ticks, {n_los} lines")
    return gemms, eigs, rows


def exact_floor(camp, runner) -> tuple:
    """The exact floor of one Monte Carlo sample on one core, two ways.

    Parameters
    ----------
    camp : Campaign
        The Monte Carlo campaign.
    runner : LinearRunner
        Its runner.

    Returns
    -------
    (gflop, rate, t_bound, t_shapes, rows)
        Flops of the products (GFlop; eigenvalues at ``10 n^3``), this machine's
        one-thread square dgemm rate (GFlop/s), ``gflop / rate`` (s, a lower bound), the
        same products and eigenvalues timed in their own shapes (s), and the sizes.
    """
    one_blas_thread()
    gemms, eigs, rows = _products(camp, runner)
    rng = np.random.default_rng(0)
    flop = (sum(2.0 * c * m * k * n for c, m, k, n in gemms)
            + sum(10.0 * P.shape[0]**3 for P in eigs))
    n = max(P.shape[0] for P in eigs)
    A, B = rng.standard_normal((n, n)), rng.standard_normal((n, n))
    rate = 2.0 * n**3 * 20 / best_of(lambda: [A @ B for _ in range(20)], 5)[0] / 1e9
    t_shapes = 0.0
    for c, m, k, nn in gemms:
        X, Y = rng.standard_normal((m, k)), rng.standard_normal((k, nn))
        t_shapes += c * best_of(lambda: X @ Y, 5)[0]
    for P in eigs:   # the nominal loop's own map: its eigenvalues converge as a sample's
        t_shapes += best_of(lambda: np.linalg.eigvals(P), 3)[0]
    return flop / 1e9, rate, flop / 1e9 / rate, t_shapes, rows


def formulations(ctx: dict) -> list:
    """What rules out cheaper exact formulations of a sample, measured on the nominal loops.

    Parameters
    ----------
    ctx : dict
        The Monte Carlo's compiled nominal loops (``montecarlo._setup``).

    Returns
    -------
    list of str
        Per configuration, the density of the tick map the long runs apply (a sparse or
        block-diagonal one would make the Krylov products and powers cheap), its
        eigenvalues at 1 and the condition number of its eigenvector matrix (a
        diagonalisable, well-conditioned map would give every power in its eigenbasis);
        then the band of the static Ritz block's modes (fast ones could be made static).
    """
    import scipy.linalg as la

    out = []
    for cf in ctx["configs"]:
        lin, structs, fr = ctx["base"][cf]
        sig = max(fr._runs, key=lambda r: r[1])[0]      # the long run's tick map
        M = fr._maps[sig][0]
        Mb, _ = balance(M)
        w, V = np.linalg.eig(Mb)
        out.append(f"{cf}: tick map {np.count_nonzero(M) / M.size:.0%} non-zero, "
                   f"{int(np.sum(np.abs(w - 1.0) < 1e-6))} eigenvalues at 1, eigenvector "
                   f"condition {np.linalg.cond(V):.1e}")
    model = ctx["base"][ctx["configs"][0]][0].blocks[ctx["base"][ctx["configs"][0]][1][0]].model
    if model.n_ritz:
        w2, V2 = la.eigh(model.K_oo)
        f = np.sqrt(np.abs(w2)) / (2.0 * np.pi)
        zeta = np.diag(V2.T @ model.D_oo @ V2) / (2.0 * np.sqrt(np.abs(w2)))
        out.append(f"static Ritz block: {model.n_ritz} modes at {f.min():.0f}-{f.max():.0f} Hz "
                   f"(median {np.median(f):.0f} Hz), damping {zeta.min():.3f}-{zeta.max():.3f}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=20)
    ap.add_argument("--fmu-dir", default="fmus")
    ap.add_argument("--workers", type=int, default=2, help="Monte Carlo worker processes")
    ap.add_argument("--repeat", type=int, default=3,
                    help="sweeps from scratch, each on a fresh runner")
    ap.add_argument("--core-samples", type=int, default=6,
                    help="samples timed on one core in this process")
    ap.add_argument("--no-floor", dest="floor", action="store_false",
                    help="leave out the exact floor of a sample")
    ap.add_argument("--no-sweep", dest="sweep", action="store_false",
                    help="leave out the RWA sweep")
    ap.add_argument("--modes", default="70,140,280,500",
                    help="mode counts of the scaling comparison ('' leaves it out)")
    ap.add_argument("--json", default=None, help="write the numbers to this file")
    ap.add_argument("--verdicts", type=int, default=0,
                    help="samples whose stability verdicts both engines give (0: none)")
    args = ap.parse_args(argv)
    if args.samples < 1 or args.core_samples < 1:
        ap.error("--samples and --core-samples count samples; give at least 1 each")
    warnings.simplefilter("ignore")
    fmu_dir = eos.ensure_fmus(args.fmu_dir)
    budget = load_campaign(eos.CAMPAIGN)
    sweep = load_campaign(eos.CAMPAIGN.parent / "eos_rwa_sweep.toml")
    with tempfile.TemporaryDirectory(prefix="bench-analyses-") as tmp:
        tmp = Path(tmp)
        # the alternative's unit: one co-simulated case
        rwa = next(c for c in budget.cases if c.event == "RWA")
        master = MasterRunner(budget.scenario_dir, fmu_dir=fmu_dir)
        master(rwa.scenario, tmp / "warm")
        t0 = time.perf_counter()
        master(rwa.scenario, tmp / "one")
        t_case = time.perf_counter() - t0

        scratch, t_again = [float("nan")], float("nan")
        for i in range(max(1, args.repeat) if args.sweep else 0):
            runner = LinearRunner(sweep.scenario_dir, fmu_dir=fmu_dir)
            for sw in sweep.wheel_sweeps:
                runner.compiled(sw["scenario"])      # the model build
            t0 = time.perf_counter()
            run_wheel_sweeps(sweep, tmp / f"sweep{i}", runner)
            scratch.append(time.perf_counter() - t0)
        if args.sweep:
            scratch = scratch[1:]
            # again on the same loops: their open-ACS loops and factorisations are kept,
            # what a second range, wheel or metric on a configuration costs
            t0 = time.perf_counter()
            run_wheel_sweeps(sweep, tmp / "sweep2", runner)
            t_again = time.perf_counter() - t0
        t_sweep = float(np.median(scratch))

        # the Monte Carlo of the shipped uncertainty file (campaigns/eos_uncertainty.toml)
        unc_file = eos.CAMPAIGN.parent / "eos_uncertainty.toml"
        lrun = LinearRunner(budget.scenario_dir, fmu_dir=fmu_dir)
        rss = {}
        for n in sorted({max(1, args.samples // 4), args.samples}):
            camp = load_campaign(eos.CAMPAIGN, unc_file, n)
            (tmp / f"mc{n}").mkdir()
            t0 = time.perf_counter()
            run_uncertainty(camp, tmp / f"mc{n}", lrun, progress=False, workers=args.workers)
            t_mc, rss[n] = time.perf_counter() - t0, peak_rss_mb()
        # one core, in this process: the cost of a sample itself (no start-up, no pool)
        one_blas_thread()
        ctx = mcm._setup(camp, lrun)
        lin0, structs, _ = ctx["base"][ctx["configs"][0]]
        draws = draw(camp.uncertainty["parameters"], args.core_samples + 1,
                     camp.uncertainty["seed"], lin0.blocks[structs[0]].model.frequencies_hz)
        mcm._evaluate(camp, lrun, ctx, draws, [0])          # first use: run types built
        t0 = time.perf_counter()
        mcm._evaluate(camp, lrun, ctx, draws, list(range(1, args.core_samples + 1)))
        t_core = (time.perf_counter() - t0) / args.core_samples
        side = _structured.per_sample(camp, lrun, ctx, args.core_samples)
        s_gflop, nz_gflop, s_rows = _structured.structured_flops(camp, lrun, ctx)
        parts = _structured.stages(camp, lrun, ctx, args.core_samples)
        modes = [int(m) for m in args.modes.split(",") if m.strip()]
        scale = (_structured.scaling(camp, lrun, ctx, modes, args.core_samples) if modes
                 else [])
        votes = _structured.verdicts(camp, ctx, args.verdicts) if args.verdicts else {}
        with _structured.engine(ctx, "dense"):
            floor = exact_floor(camp, lrun) if args.floor else None
            forms = formulations(ctx) if args.floor else []
    kernels = blas_choice()
    print(f"OpenBLAS kernels: {kernels}")
    print(f"one co-simulated EOS case (8 s at 1 kHz, native FMUs): {t_case:.2f} s")
    print(f"{'analysis':<48}{'linear (s)':>12}{'co-simulation (s)':>20}")
    print(f"{'RWA sweep, 500 speeds x 15 axes x 2 configs':<48}{t_sweep:>12.2f}"
          f"{2 * 500 * t_case:>20.0f}  (500 cases per configuration, estimated)")
    if len(scratch) > 1:
        print(f"  (median of {len(scratch)} from scratch, {min(scratch):.2f}-"
              f"{max(scratch):.2f} s)")
    print(f"{'  the same again, loops kept (per-speed work only)':<48}{t_again:>12.2f}")
    cores = args.workers
    print(f"{'Monte Carlo, one sample (24 records), one core':<48}{t_core:>12.3f}"
          f"{24 * t_case:>20.1f}  (mean of {args.core_samples} in this process)")
    print(f"{f'Monte Carlo, 1000 samples on {cores} cores (at that)':<48}"
          f"{1000 * t_core / cores:>12.0f}{24000 * t_case / cores:>20.0f}")
    print(f"{f'  a {args.samples}-sample run, {cores} workers, per sample':<48}"
          f"{t_mc / args.samples:>12.3f}   (the whole command: start-up, pool, statistics, "
          "files)")
    print("peak memory: " + ", ".join(f"{v:.0f} MB after {n} samples" for n, v in rss.items())
          + " (a sample keeps its metrics only: it does not grow with the samples)")
    if floor is not None:
        gflop, rate, t_bound, t_shapes, rows = floor
        print("exact floor of a sample (the products it cannot leave out; one core):")
        for r in rows:
            print(f"  {r}")
        print(f"  {gflop:.1f} GFlop at {rate:.0f} GFlop/s (square dgemm here, OpenBLAS "
              f"kernels {kernels}): {t_bound:.3f} s "
              f"-> 1000 samples on {cores} cores >= {1000 * t_bound / cores:.0f} s")
        print(f"  the same products timed in their shapes: {t_shapes:.3f} s -> "
              f"{1000 * t_shapes / cores:.0f} s for 1000 on {cores} cores")
        print(f"  measured: {t_core:.3f} s a sample, {t_core / t_bound:.1f}x the floor; the "
              f"issue's 60 s for 1000 on {cores} cores is {60 * cores / 1000:.3f} s a sample")
        print("what rules out cheaper exact formulations (nominal loops):")
        for r in forms:
            print(f"  {r}")
    rate = floor[1] if floor is not None else _structured.dgemm_rate()
    print("structured against dense, the same samples, one core, interleaved:")
    print(f"  a sample: structured {side['structured_s']:.3f} s, dense {side['dense_s']:.3f} s "
          f"({side['dense_s'] / side['structured_s']:.2f}x), median of {side['samples']}; "
          f"metrics within {side['largest_metric_difference']:.1e}, statuses "
          f"{'equal' if side['statuses_equal'] else 'DIFFERENT'}"
          + ("" if side["engines_as_named"] else "; NOT every sample ran on the loop its "
             "engine names (a structured sample ran dense, or the reverse)"))
    print(f"  1000 samples on {cores} cores at that: structured "
          f"{1000 * side['structured_s'] / cores:.0f} s, dense {1000 * side['dense_s'] / cores:.0f}"
          f" s; a co-simulated case on one core {t_case:.2f} s (a sample is "
          f"{side['structured_s'] / t_case:.2f} of it)")
    print("  where a structured sample's time goes (median ms on one core):")
    for cf, v in parts.items():
        print(f"    {cf} (memory state {v['memory_state']}): " + ", ".join(
            f"{k} {1e3 * v[k]:.1f}" for k in ("structure block", "run types", "poles",
                                              "records")))
    print(f"  structured floor: {s_gflop:.2f} GFlop a sample at {rate:.0f} GFlop/s -> "
          f"{s_gflop / rate:.3f} s ({nz_gflop:.2f} GFlop, {nz_gflop / rate:.3f} s, with "
          "the zero entries of the tick maps' coupling left out of its products)")
    for r in s_rows:
        print(f"    {r}")
    if scale:
        cfs = list(scale[0]["stages_s"])
        print(f"  {'modes':>6}{'memory states':>16}{'structured (s)':>16}{'dense (s)':>11}"
              f"{'forms (MB)':>12}  poles (ms; " + ", ".join(cfs) + ")")
        for r in scale:
            poles = "/".join(f"{1e3 * r['stages_s'][cf]['poles']:.1f}" for cf in cfs)
            print(f"  {r['modes']:>6}{'/'.join(map(str, r['memory_states'])):>16}"
                  f"{r['structured_s']:>16.3f}{r['dense_s']:>11.3f}"
                  f"{r['form_bytes'] / 1e6:>12.1f}  {poles}")
        if len(scale) > 1:
            print(f"  cost ~ s^{_structured.exponent(scale, 'structured_s'):.2f} structured, "
                  f"s^{_structured.exponent(scale, 'dense_s'):.2f} dense (s the memory state)")
            for cf in cfs:   # what the slope would be without one stage: the poles
                slope = _structured.exponent(scale, "structured_s",
                                             lambda r, cf=cf: r["stages_s"][cf]["poles"])
                print(f"  structured without the poles of {cf}: s^{slope:.2f}")
    for cf, v in votes.items():
        print(f"  stability of {args.verdicts} samples, {cf}: {v['agree']} verdicts equal; "
              f"unstable {v['unstable_structured']} structured, {v['unstable_dense']} dense "
              f"(eigenvalues); loop and poles {v['structured_s']:.1f} s against "
              f"{v['dense_s']:.1f} s")
    if args.json:
        import json
        Path(args.json).write_text(json.dumps({
            "cosim_case_s": t_case, "sweep_s": t_sweep, "mc_per_sample_one_core_s": t_core,
            "mc_run_per_sample_s": t_mc / args.samples, "workers": cores,
            "peak_rss_mb": {str(k): v for k, v in rss.items()}, **side,
            "structured_gflop": s_gflop, "structured_nonzero_gflop": nz_gflop,
            "dgemm_gflops": rate, "blas_kernels": kernels,
            "dense_floor_gflop": floor[0] if floor is not None else None,
            "stages_s": parts, "scaling": scale, "verdicts": votes}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
