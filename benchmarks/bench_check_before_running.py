"""A misspelt instrument variable: refused before any case runs, next to found after one.

Run::

    .venv/bin/python benchmarks/bench_check_before_running.py [--fmu-dir fmus]

The shipped quick truss campaign (``campaigns/truss10_quick.toml``, 4 cases of 3 s) with
``structure.los_tip_roll`` misspelt ``structure.los_tip_rol``, side by side in one run:

* ``checked``: :func:`orchestrator.campaign.run_campaign` as it is, which checks the
  instrument variables against the FMUs before any case runs and refuses the campaign
  in one sentence with the closest names;
* ``found late``: the same with that check left out (as it was before), where the first
  case co-simulates and only then fails on the missing variable; the time until that
  first failure is what a user waited before learning of the typo (each of the four
  cases then fails the same way).

Both times include loading the campaign and reading the FMUs; the FMUs must be built
(``jitterfmu build`` or ``make demo``).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def misspelt_campaign(folder: Path) -> Path:
    """The quick truss campaign with the roll axis misspelt, its scenario absolute."""
    text = (ROOT / "campaigns" / "truss10_quick.toml").read_text()
    text = text.replace('"../scenarios/truss10_campaign.toml"',
                        repr(str(ROOT / "scenarios" / "truss10_campaign.toml")))
    path = folder / "c.toml"
    path.write_text(text.replace("structure.los_tip_roll", "structure.los_tip_rol", 1))
    return path


def main(argv=None) -> int:
    """Time both ways; print one line each."""
    from orchestrator.campaign import CampaignError, engine, load_campaign, run_campaign
    from orchestrator.campaign.runner import MasterRunner

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmu-dir", default=str(ROOT / "fmus"), help="built FMUs (default: fmus)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        camp = load_campaign(misspelt_campaign(tmp))
        runner = MasterRunner(camp.scenario_dir, fmu_dir=args.fmu_dir)
        try:
            run_campaign(camp, tmp / "checked", runner, workers=0, progress=False)
            print("checked: not refused (unexpected)")
            return 1
        except CampaignError as exc:
            checked = time.perf_counter() - t0
            print(f"checked:    refused after {checked:6.2f} s, no case run: {exc}")

        t0 = time.perf_counter()
        camp = load_campaign(misspelt_campaign(tmp))
        one = dataclasses.replace(camp, cases=camp.cases[:1])
        kept = engine._check_overrides
        engine._check_overrides = lambda campaign, runner: None    # as before the check
        try:
            res = run_campaign(one, tmp / "late", MasterRunner(camp.scenario_dir,
                                                               fmu_dir=args.fmu_dir),
                               workers=0, progress=False)
        finally:
            engine._check_overrides = kept
        late = time.perf_counter() - t0
        why = next(iter(res.failures.values()), "no failure (unexpected)")
        print(f"found late: first case failed after {late:6.2f} s: {why}")
        print(f"the check answers {late / checked:.0f} times sooner, and the campaign's "
              f"{len(camp.cases)} cases would each have failed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
