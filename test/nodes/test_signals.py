"""Ctrl-C and SIGTERM on real node processes: exit 0, no traceback, promptly, at any phase.

``ros2 launch`` sends SIGINT to every node and escalates with SIGTERM; users press Ctrl-C twice.
The entry point (``nodes/common.py`` ``run``) must end cleanly whether the signals come during
start-up, while spinning, or while the node is being destroyed.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time

import pytest

pytestmark = pytest.mark.ros

# A packetizer node whose start-up and destroy_node are slow and say when they begin, so that a
# signal surely lands inside them (the real ones take milliseconds).
SLOW_NODE = """
import sys, time
from hrn_vo_ros.nodes.process import run
from hrn_vo_ros.nodes.packetizer_node import PacketizerNode

class Slow(PacketizerNode):
    def __init__(self):
        if 'start' in sys.argv:
            print('starting', flush=True)
            time.sleep(1.0)
        super().__init__()
        print('spinning', flush=True)

    def destroy_node(self):
        print('destroying', flush=True)
        time.sleep(0.5)
        print('destroyed', flush=True)
        return super().destroy_node()

sys.exit(run(Slow))
"""
TIMEOUT = 30.0


def start(argv: list[str]) -> subprocess.Popen[str]:
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    return subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def wait_line(proc: subprocess.Popen[str], stream: str, text: str) -> None:
    """Block (bounded) until a line of ``stream`` contains ``text``."""
    pipe = proc.stdout if stream == 'stdout' else proc.stderr
    assert pipe is not None
    end = time.monotonic() + TIMEOUT
    while time.monotonic() < end:
        ready, _, _ = select.select([pipe], [], [], 0.1)
        if ready:
            line = pipe.readline()
            if text in line:
                return
            if not line and proc.poll() is not None:
                break
    proc.kill()
    pytest.fail(f'no {text!r} on {stream} of {proc.args}')


def ended(proc: subprocess.Popen[str], sent: float) -> tuple[str, str, float]:
    """(stdout, stderr, seconds since ``sent``) once the process ended; fails after
    ``TIMEOUT``."""
    try:
        out, err = proc.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        pytest.fail(f'still running {TIMEOUT} s after the signals: {err[-2000:]}')
    return out, err, time.monotonic() - sent


def finish(proc: subprocess.Popen[str], sent: float, limit: float = 10.0) -> str:
    """Exit code 0, no traceback, within ``limit`` seconds of the first signal."""
    out, err, took = ended(proc, sent)
    assert proc.returncode == 0, f'exit {proc.returncode}: {err[-2000:]}'
    assert 'Traceback' not in err and 'Traceback' not in out, err[-2000:]
    assert took < limit, f'took {took:.1f} s to exit'
    return out


def test_two_quick_sigints_while_spinning() -> None:
    proc = start([sys.executable, '-m', 'hrn_vo_ros.nodes.packetizer_node'])
    wait_line(proc, 'stderr', 'events per frame')      # logged at the end of __init__
    time.sleep(0.3)                                     # spinning now
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    finish(proc, sent)


def test_second_sigint_inside_destroy_node_and_sigterm_after() -> None:
    proc = start([sys.executable, '-c', SLOW_NODE])
    wait_line(proc, 'stdout', 'spinning')
    time.sleep(0.3)                                     # constructed and returned: spinning
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    wait_line(proc, 'stdout', 'destroying')
    proc.send_signal(signal.SIGINT)                     # what ros2 launch sends on a 2nd Ctrl-C
    time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)                    # and its escalation
    out = finish(proc, sent)
    assert 'destroyed' in out                           # the clean-up ran to its end


@pytest.mark.parametrize('first, second', [(signal.SIGTERM, signal.SIGTERM),
                                           (signal.SIGINT, signal.SIGTERM)])
def test_signals_during_start_up(first: signal.Signals, second: signal.Signals) -> None:
    proc = start([sys.executable, '-c', SLOW_NODE, 'start'])
    wait_line(proc, 'stdout', 'starting')               # inside make_node, after rclpy.init
    sent = time.monotonic()
    proc.send_signal(first)
    time.sleep(0.02)
    proc.send_signal(second)
    out = finish(proc, sent)
    assert 'spinning' not in out                        # stopped during start-up


# Nodes that never finish stopping: their clean-up, or a callback that holds the main thread in
# C with the stop signals blocked (so the signal reaches rclpy's handler, which shuts the
# context down, but the main thread never sees it). A stop limit of 1 s ends them (exit 1) and
# names where they were; run() disarms it when it returns, so a caller can go on.
STUCK_NODE = """
import signal, sys, time
import rclpy
from hrn_vo_ros.nodes.process import run
from hrn_vo_ros.nodes.packetizer_node import PacketizerNode

class Stuck(PacketizerNode):
    def __init__(self):
        super().__init__()
        self.create_timer(0.05, self.on_timer)
        print('spinning', flush=True)

    def on_timer(self):
        if 'callback' in sys.argv:
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
            print('stuck', flush=True)
            time.sleep(60)
        if 'returns' in sys.argv:
            rclpy.try_shutdown()
        if 'raise' in sys.argv:       # a real error: the clean-up begins, the context is ok
            raise RuntimeError('a bug in a callback')

    def destroy_node(self):
        if 'destroy' in sys.argv:
            print('destroying', flush=True)
            time.sleep(60)
        return super().destroy_node()

code = run(Stuck, stop_limit_s=1.0)
time.sleep(2.0)
print('went on', flush=True)
sys.exit(code)
"""


@pytest.mark.parametrize('where, line, frame', [('destroy', 'destroying', 'destroy_node'),
                                                ('callback', 'stuck', 'on_timer'),
                                                ('raise destroy', 'destroying', 'destroy_node')])
def test_a_stop_that_hangs_ends_within_the_limit_and_names_where(
        where: str, line: str, frame: str) -> None:
    proc = start([sys.executable, '-c', STUCK_NODE, *where.split()])
    wait_line(proc, 'stdout', line if where != 'destroy' else 'spinning')
    time.sleep(0.3)
    sent = time.monotonic()
    if where != 'raise destroy':          # (that one is stopping by itself)
        proc.send_signal(signal.SIGINT)
    out, err, took = ended(proc, sent)
    assert proc.returncode == 1, (proc.returncode, err[-2000:])
    # the limit from the signal (or, stopping by itself, from before the line), the period
    assert (1.0 if where != 'raise destroy' else 0.3) <= took < 6.0, took
    assert 'Timeout' in err and f'in {frame}' in err, err[-2000:]
    assert 'went on' not in out


def test_the_stop_limit_is_disarmed_when_run_returns() -> None:
    proc = start([sys.executable, '-c', STUCK_NODE, 'returns'])
    out = finish(proc, time.monotonic(), limit=20.0)
    assert 'went on' in out                     # 2 s after run() returned, past the 1 s limit


# A one-job node (as bag_player) run by run_task: its job prints and sleeps (or fails), its
# destroy_node may be slow or hang; the stop limit is 1 s.
TASK_NODE = """
import sys, time
from rclpy.node import Node
from hrn_vo_ros.errors import BagError
from hrn_vo_ros.nodes.process import run_task

class Job(Node):
    def __init__(self):
        super().__init__('job')

    def work(self):
        print('working', flush=True)
        if 'bad' in sys.argv:
            raise BagError('no such bag')
        time.sleep(0.2 if 'quick' in sys.argv else 60)
        return 7

    def destroy_node(self):
        print('destroying', flush=True)
        time.sleep(60 if 'hang' in sys.argv else 0.5)
        print('destroyed', flush=True)
        return super().destroy_node()

code = run_task(Job, Job.work, stop_limit_s=1.0)
time.sleep(1.5)
print('went on', flush=True)
sys.exit(code)
"""


def test_a_job_stopped_twice_exits_130_after_its_whole_clean_up() -> None:
    proc = start([sys.executable, '-c', TASK_NODE])
    wait_line(proc, 'stdout', 'working')
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    wait_line(proc, 'stdout', 'destroying')
    proc.send_signal(signal.SIGINT)                     # inside the clean-up: ignored
    time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    out, err, took = ended(proc, sent)
    assert proc.returncode == 130, (proc.returncode, err[-2000:])
    assert 'Traceback' not in err and 'destroyed' in out and took < 5.0, (err[-2000:], took)


@pytest.mark.parametrize('how, code', [('quick', 7), ('bad', 4)])
def test_a_job_that_ends_gives_its_code_and_the_caller_goes_on(how: str, code: int) -> None:
    """The job's own code, or a package error's exit code (a BagError: 4) with its message
    logged; the stop limit is disarmed on return (the caller outlives it)."""
    proc = start([sys.executable, '-c', TASK_NODE, how])
    out, err, _ = ended(proc, time.monotonic())
    assert proc.returncode == code, (proc.returncode, err[-2000:])
    assert 'went on' in out and 'destroyed' in out and 'Traceback' not in err, err[-2000:]
    assert ('no such bag' in err) == (how == 'bad')


def test_a_job_whose_clean_up_hangs_ends_within_the_limit() -> None:
    proc = start([sys.executable, '-c', TASK_NODE, 'quick', 'hang'])
    wait_line(proc, 'stdout', 'destroying')
    out, err, took = ended(proc, time.monotonic())
    assert proc.returncode == 1 and 'in destroy_node' in err, (proc.returncode, err[-2000:])
    assert took < 5.0 and 'went on' not in out, took


def test_a_job_whose_arguments_rclpy_refuses_fails_with_that_error_not_130() -> None:
    """An error before rclpy is initialised is no stop signal's doing: it is raised (exit 1,
    rcl's message), not reported as interrupted."""
    code = ('import sys\nfrom rclpy.node import Node\nfrom hrn_vo_ros.nodes.process import '
            "run_task\nsys.exit(run_task(Node, lambda n: 0, ['x', '--ros-args', '--remap']))\n")
    proc = start([sys.executable, '-c', code])
    _, err, _ = ended(proc, time.monotonic())
    assert proc.returncode == 1 and "Couldn't parse trailing --remap flag" in err, err[-2000:]


# A node that records the executor run() spins it with, and says in destroy_node whether that
# executor was already shut down; or one whose callback crashes in C (a null read).
EXECUTOR_NODE = """
import ctypes, sys
import hrn_vo_ros.nodes.process as process
from hrn_vo_ros.nodes.packetizer_node import PacketizerNode

made = []
make = process._executor
process._executor = lambda: made.append(make()) or made[-1]

class Node(PacketizerNode):
    def __init__(self):
        super().__init__()
        if 'crash' in sys.argv:
            self.create_timer(0.2, self.crash_in_c)
        print('spinning', flush=True)

    def crash_in_c(self):
        ctypes.string_at(0)

    def destroy_node(self):
        gone = made[0]._guard is None and made[0]._sigint_gc is None
        print('executor ' + ('shut down' if gone else 'alive'), flush=True)
        return super().destroy_node()

sys.exit(process.run(Node))
"""


def test_the_executor_is_shut_down_before_the_node_is_destroyed() -> None:
    proc = start([sys.executable, '-c', EXECUTOR_NODE])
    wait_line(proc, 'stdout', 'spinning')
    time.sleep(0.3)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    assert 'executor shut down' in finish(proc, sent)


def test_a_crash_in_c_prints_where_it_happened() -> None:
    proc = start([sys.executable, '-c', EXECUTOR_NODE, 'crash'])
    out, err, _ = ended(proc, time.monotonic())
    assert proc.returncode == -signal.SIGSEGV, (proc.returncode, err[-2000:])
    assert 'Fatal Python error: Segmentation fault' in err, err[-2000:]
    assert 'in crash_in_c' in err, err[-2000:]


def test_no_rclpy_object_outlives_run() -> None:
    """run() ends with the node, its executor and its context collected (not left to the
    interpreter's finalization), also when the stop limit's watchdog looks at the context
    after its shutdown (a clean-up longer than its period: rclpy.ok() there made a new
    default context that outlived run)."""
    script = """
import gc, sys, time, weakref
import rclpy
from rclpy.context import Context
from rclpy.executors import Executor
from hrn_vo_ros.nodes.process import run
from hrn_vo_ros.nodes.packetizer_node import PacketizerNode
from hrn_vo_ros.nodes.stop_limit import WATCH_PERIOD_S

class Node(PacketizerNode):
    def __init__(self):
        super().__init__()
        self.create_timer(0.3, rclpy.try_shutdown)
        ctx.append(weakref.ref(self.context))

def slow_full_collection(phase, info):     # run's last gc.collect, after the shutdown
    context = ctx[0]() if ctx else None
    if phase == 'start' and info['generation'] == 2 and ctx and not (context and context.ok()):
        time.sleep(2 * WATCH_PERIOD_S)

ctx = []
gc.callbacks.append(slow_full_collection)

code = run(Node)
live = [type(o).__name__ for o in gc.get_objects()
        if isinstance(o, (Context, Executor, PacketizerNode))]
print('live', live, flush=True)
sys.exit(code)
"""
    proc = start([sys.executable, '-c', script])
    assert 'live []' in finish(proc, time.monotonic())


def test_the_clean_up_ends_the_stop_limits_watchdog_first() -> None:
    """stop_watching ends the watchdog thread within about a period while the context is still
    ok (the clean-up then destroys the node with no other thread touching rclpy); the clean-up
    order arms the limit and ends the watchdog before the node goes."""
    import rclpy

    from hrn_vo_ros.nodes import process
    from hrn_vo_ros.nodes.stop_limit import StopLimit, WATCH_PERIOD_S

    rclpy.init()
    limit = StopLimit(60.0)
    try:
        limit.watch()
        thread = limit._thread
        assert thread is not None and thread.is_alive()
        t0 = time.monotonic()
        limit.stop_watching()
        assert not thread.is_alive() and time.monotonic() - t0 < 2.0 * WATCH_PERIOD_S
    finally:
        limit.disarm()
        rclpy.try_shutdown()
    calls: list[str] = []

    class Node:
        def destroy_node(self) -> None:
            calls.append('destroy')

    class Limit:
        def arm(self) -> None:
            calls.append('arm')

        def stop_watching(self) -> None:
            calls.append('stop_watching')

    process._shut_down(Node(), Limit())       # type: ignore[arg-type]
    assert calls == ['arm', 'stop_watching', 'destroy']
