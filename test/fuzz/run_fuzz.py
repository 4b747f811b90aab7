"""Run the fuzz targets as their own step: each target in its own pytest process, N at a time.

``scripts/test.sh`` calls this after the main pytest run (never alongside it: the ROS tests are
timing-sensitive). Each target runs ``HRN_FUZZ_SECONDS`` (default 5; ``.ci/run`` sets 60),
``HRN_FUZZ_JOBS`` targets at a time (default 2, the CI machine's cores). Every target's run is
recorded by ``fuzzlib.run_for`` (seconds, inputs, rounds, outcome) and printed here as one line
when it ends, then as a table. The step fails when a target fails (crash, wrong result, hang
past its hard limit) or ran less than its budget; a failing target's pytest output (with the
shrunk input) is printed.

    scripts/run.sh python test/fuzz/run_fuzz.py                      # 5 s per target
    HRN_FUZZ_SECONDS=60 scripts/run.sh python test/fuzz/run_fuzz.py  # as in CI
    scripts/run.sh python test/fuzz/run_fuzz.py -k ros2_bag --jobs 1
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def say(line: str) -> None:
    """One line of the step's log, flushed (the CI log shows each target as it ends)."""
    sys.stdout.write(line + '\n')
    sys.stdout.flush()


@dataclass
class Job:
    """One pytest process running one fuzz target (or the corpus check)."""

    nodeid: str
    proc: subprocess.Popen[bytes]
    log: Path
    report: Path
    started: float


def collect(select: str | None) -> list[str]:
    """The node ids under test/fuzz (``-k`` applied)."""
    cmd = [sys.executable, '-m', 'pytest', '--collect-only', '-q', '-p', 'no:cacheprovider',
           str(HERE.relative_to(ROOT))]
    if select:
        cmd += ['-k', select]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    ids = [line.strip() for line in out.stdout.splitlines() if '::' in line]
    if out.returncode not in (0, 5) or (not ids and out.returncode != 5):
        sys.stdout.write(out.stdout + out.stderr)
        raise SystemExit(f'[fuzz] collecting the targets failed (pytest exit {out.returncode})')
    return ids


def start(nodeid: str, work: Path, seconds: float, index: int) -> Job:
    """A pytest process for one node id, its output in a log file."""
    log = work / f'{index:02d}.log'
    report = work / f'{index:02d}.jsonl'
    env = {**os.environ, 'HRN_FUZZ_SECONDS': f'{seconds:g}', 'HRN_FUZZ_REPORT': str(report)}
    with open(log, 'wb') as out:
        proc = subprocess.Popen(
            [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', nodeid],
            cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    return Job(nodeid, proc, log, report, time.monotonic())


def records(job: Job) -> list[dict[str, object]]:
    """The FuzzRun records the job wrote."""
    if not job.report.exists():
        return []
    return [json.loads(line) for line in job.report.read_text().splitlines() if line.strip()]


def main(argv: list[str] | None = None) -> int:
    """Run the targets and print their records; 0 when every one passed its full budget."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--seconds', type=float,
                    default=float(os.environ.get('HRN_FUZZ_SECONDS', '5')),
                    help='budget per target (default $HRN_FUZZ_SECONDS or 5)')
    ap.add_argument('--jobs', type=int, default=int(os.environ.get('HRN_FUZZ_JOBS', '2')),
                    help='targets at a time (default $HRN_FUZZ_JOBS or 2)')
    ap.add_argument('-k', dest='select', help='pytest -k expression over the targets')
    args = ap.parse_args(argv)
    if not (args.seconds > 0 and args.jobs >= 1):
        ap.error('--seconds must be > 0 and --jobs >= 1')
    # A round of 50 examples can overrun the budget (2 s deadline each); past this the
    # target counts as hung and is killed.
    limit = 2 * args.seconds + 240.0
    ids = collect(args.select)
    say(f'[fuzz] {len(ids)} tests, {args.seconds:g} s per target, {args.jobs} at a time, '
          f'hard limit {limit:.0f} s each')
    t0 = time.monotonic()
    failed: list[str] = []
    rows: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory(prefix='hrn_fuzz_run_') as tmp:
        work = Path(tmp)
        pending = list(enumerate(ids))
        running: list[Job] = []
        while pending or running:
            while pending and len(running) < args.jobs:
                index, nodeid = pending.pop(0)
                running.append(start(nodeid, work, args.seconds, index))
            time.sleep(0.2)
            for job in list(running):
                rc = job.proc.poll()
                hung = rc is None and time.monotonic() - job.started > limit
                if rc is None and not hung:
                    continue
                if hung:
                    os.killpg(job.proc.pid, signal.SIGKILL)
                    rc = job.proc.wait()
                running.remove(job)
                recs = records(job)
                rows += recs
                short = [r for r in recs if float(str(r['seconds'])) < args.seconds]
                wall = time.monotonic() - job.started
                if recs:
                    for r in recs:
                        say(f'[fuzz] {r["target"]}: {float(str(r["seconds"])):.1f} s, '
                              f'{r["inputs"]} inputs in {r["rounds"]} rounds: {r["outcome"]}')
                else:
                    say(f'[fuzz] {job.nodeid}: not a fuzz target, {wall:.1f} s')
                if hung or rc != 0 or short:
                    why = (f'hung: killed after {limit:.0f} s' if hung else
                           f'pytest exit {rc}' if rc != 0 else 'ran less than its budget')
                    failed.append(f'{job.nodeid} ({why})')
                    say(f'[fuzz] FAILED {job.nodeid}: {why}; its output:')
                    sys.stdout.write(job.log.read_text(errors='replace')[-20000:])
                    sys.stdout.flush()
    wall = time.monotonic() - t0
    say('[fuzz] | Target | Seconds | Inputs | Outcome |')
    for r in rows:
        say(f'[fuzz] | `{r["target"]}` | {float(str(r["seconds"])):.1f} | {r["inputs"]} | '
              f'{r["outcome"]} |')
    total = sum(int(str(r['inputs'])) for r in rows)
    say(f'[fuzz] {len(rows)} targets, {total} inputs, {wall:.0f} s wall; '
          + (f'{len(failed)} FAILED: {", ".join(failed)}' if failed else 'no failure'))
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
