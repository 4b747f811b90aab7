"""The real ROS 2 tools drive the package: ``ros2 run``, ``ros2 launch``, ``ros2 param``.

These need ``launch``, ``launch_ros`` and the ``ros2`` command (a ROS 2 Jazzy install, or the
wheels scripts/setup.sh installs from ../shared/ros2/wheels); they skip, saying why, without.
Every command runs in this test run's own ROS_DOMAIN_ID (test/conftest.py) with ``--no-daemon``;
every process started here is stopped at the end (SIGINT to its process group, then SIGKILL,
with bounded waits), and a ros2 daemon of this domain, if any, is stopped.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
import contextlib
import importlib.util
import os
from pathlib import Path
import shutil
import signal
import subprocess
import time

import pytest

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / 'config' / 'shapes_rotation.yaml'
MISSING = [m for m in ('launch', 'launch_ros', 'ros2cli') if importlib.util.find_spec(m) is None]
pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(bool(MISSING) or shutil.which('ros2') is None,
                       reason=f'the ROS 2 tools are not installed (missing: '
                              f'{", ".join(MISSING) or "the ros2 command"}): source ROS 2 Jazzy, '
                              'or run scripts/setup.sh with ../shared/ros2/wheels present'),
]


def ros2(*args: str, timeout: float = 40.0) -> subprocess.CompletedProcess[str]:
    """Run one ``ros2`` command to completion (bounded), capturing its output."""
    return subprocess.run(['ros2', *args], capture_output=True, text=True, timeout=timeout,
                          check=False, cwd=ROOT)


#: The last ``ros2 topic info`` output of :func:`counts` (shown when a wait for it fails).
LAST_INFO: list[str] = ['']


def wait_for(what: str, check: Callable[[], bool], timeout: float = 60.0,
             log: Path | None = None) -> None:
    """Poll ``check`` until it holds; fail naming ``what`` (and the last topic info, the
    nodes and topics the graph shows then, the end of ``log``) after ``timeout`` s."""
    end = time.monotonic() + timeout
    LAST_INFO[0] = ''
    while not check():
        if time.monotonic() > end:
            nodes = ros2('node', 'list', '--no-daemon', '--spin-time', '2').stdout
            pytest.fail(f'timed out after {timeout:.0f} s waiting for {what}'
                        + (f'; last ros2 topic info:\n{LAST_INFO[0]}' if LAST_INFO[0] else '')
                        + f'\nnodes:\n{nodes}topics:\n{" ".join(sorted(topics()))}'
                        + (f'\nlog (end):\n{log.read_text()[-3000:]}' if log else ''))
        time.sleep(0.5)


@contextlib.contextmanager
def started(args: list[str], log: Path, env: dict[str, str] | None = None
            ) -> Iterator[subprocess.Popen[bytes]]:
    """A process (its own process group) that is interrupted, then killed, on exit."""
    with log.open('wb') as out:
        proc = subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT, cwd=ROOT,
                                start_new_session=True, env=env)
        try:
            yield proc
        finally:
            stop(proc)


def stop(proc: subprocess.Popen[bytes]) -> None:
    """SIGINT to the process group (launch forwards it to its nodes), then SIGKILL."""
    for sig, wait in ((signal.SIGINT, 15.0), (signal.SIGKILL, 5.0)):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, sig)
        try:
            proc.wait(wait)
        except subprocess.TimeoutExpired:
            continue
        # the group may outlive its leader (nodes of a launch): make sure it is gone
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        return


@pytest.fixture(autouse=True, scope='module')
def _no_daemon_left() -> Iterator[None]:
    yield
    with contextlib.suppress(subprocess.TimeoutExpired):
        ros2('daemon', 'stop', timeout=20)


def param(node: str, name: str, tries: int = 5) -> str:
    """``ros2 param get`` output ('' while the node is not up).

    Each ``--no-daemon`` call discovers the graph anew; on a loaded machine that can miss a
    node that is up, so 'Node not found' is retried a few times before it counts.
    """
    for _ in range(tries):
        res = ros2('param', 'get', '--no-daemon', '--timeout', '5', node, name)
        if res.returncode == 0:
            return res.stdout.strip()
        time.sleep(0.5)
    return ''


def param_set(node: str, name: str, value: str, tries: int = 5) -> str:
    """``ros2 param set`` output, retried like :func:`param` while discovery is incomplete."""
    res = ros2('param', 'set', '--no-daemon', node, name, value)
    for _ in range(tries - 1):
        if 'Node not found' not in res.stderr:
            break
        time.sleep(0.5)
        res = ros2('param', 'set', '--no-daemon', node, name, value)
    return res.stdout + res.stderr


def topics() -> set[str]:
    res = ros2('topic', 'list', '--no-daemon', '--spin-time', '2')
    return set(res.stdout.split())


def counts(topic: str) -> tuple[int, int]:
    """(publishers, subscriptions) of ``topic`` from ``ros2 topic info``."""
    res = ros2('topic', 'info', '--no-daemon', '--spin-time', '2', topic)
    LAST_INFO[0] = res.stdout + res.stderr
    pubs = subs = 0
    for line in res.stdout.splitlines():
        if line.startswith('Publisher count:'):
            pubs = int(line.split(':')[1])
        elif line.startswith('Subscription count:'):
            subs = int(line.split(':')[1])
    return pubs, subs


def test_ros2_run_starts_the_resonator_and_it_publishes(tmp_path: Path) -> None:
    res = ros2('pkg', 'executables', 'hrn_vo_ros')
    assert 'hrn_vo_ros resonator_node' in res.stdout, res.stderr
    args = ['ros2', 'run', 'hrn_vo_ros', 'resonator_node', '--ros-args', '--params-file',
            str(CONFIG), '-p', 'diagnostics_period_s:=0.25']
    with started(args, tmp_path / 'run.log') as proc:
        wait_for('/resonator_node/pose in ros2 topic list',
                 lambda: '/resonator_node/pose' in topics())
        echo = ros2('topic', 'echo', '--no-daemon', '--once', '--timeout', '20',
                    '/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray')
        assert 'resonator_node' in echo.stdout, echo.stderr
        assert param('/resonator_node', 'cleanup.gamma') == 'Double value is: 0.9'
        assert proc.poll() is None, (tmp_path / 'run.log').read_text()


def test_ros2_launch_starts_both_nodes_and_param_set_takes_effect(tmp_path: Path) -> None:
    log = tmp_path / 'launch.log'
    args = ['ros2', 'launch', 'hrn_vo_ros', 'hrn_vo.launch.py', 'use_imu:=true',
            'publish_tf:=true', 'focal_px:=79.6']
    tmp = tmp_path / 'tmp'   # where the launch writes the nodes' parameter files
    tmp.mkdir()
    with started(args, log, dict(os.environ, TMPDIR=str(tmp))) as proc:
        wait_for('the resonator parameters', lambda: param('/resonator_node', 'imu.enabled')
                 == 'Boolean value is: True', timeout=150, log=log)
        assert param('/resonator_node', 'publish_tf') == 'Boolean value is: True'
        assert param('/resonator_node', 'focal_px') == 'Double value is: 79.6'
        assert param('/resonator_node', 'use_sim_time') == 'Boolean value is: False'
        assert param('/packetizer_node', 'events_per_frame') == 'Integer value is: 2000'
        # the default dataset is live.yaml: any camera (frame_size: frames, sizes from the
        # messages; the dataclass defaults say parameters and config)
        assert param('/resonator_node', 'frame_size') == 'String value is: frames'
        assert param('/packetizer_node', 'sensor_size') == 'String value is: messages'
        # ... and its start line says so, without a camera_info wait (it does not rectify)
        assert 'sensor size from the event packets, rectify none, ' in log.read_text()
        assert 'camera_info' not in log.read_text()
        # use_imu also gives the packetizer the packets of a fused gyro
        assert param('/packetizer_node', 'imu.enabled') == 'Boolean value is: True'
        # the resonator reads the packetizer's frames; the packetizer the camera topic
        wait_for('the frames link', lambda: counts('/packetizer_node/frames') == (1, 1))
        wait_for('the events subscription', lambda: counts('/event_camera/events')[1] == 1)
        # the gyro: libcaer_driver's topic by default (focal_px given: no camera_info wanted)
        wait_for('the imu subscription', lambda: counts('/event_camera/imu')[1] == 1)
        # a runtime change is validated, applied (the resonator is rebuilt) and reported
        out = param_set('/resonator_node', 'cleanup.gamma', '0.5')
        assert 'Set parameter successful' in out, out
        assert param('/resonator_node', 'cleanup.gamma') == 'Double value is: 0.5'
        wait_for('the reconfiguration log line',
                 lambda: 'resonator reconfigured' in log.read_text(), timeout=20)
        assert proc.poll() is None, log.read_text()
        # (the random part of a temporary name may hold '_' too)
        names = sorted(p.name for p in tmp.glob('hrn_vo_*'))
        assert (len(names) == 2 and names[0].startswith('hrn_vo_packetizer_node_')
                and names[1].startswith('hrn_vo_resonator_node_')), names
    # the launch removed its files when it stopped, and launch_ros wrote none of its own
    assert not [*tmp.glob('hrn_vo_*'), *tmp.glob('launch_params_*')], log.read_text()


def test_ros2_launch_under_a_namespace_keeps_remaps_and_parameters(tmp_path: Path) -> None:
    log = tmp_path / 'launch.log'
    args = ['ros2', 'launch', 'hrn_vo_ros', 'hrn_vo.launch.py', 'namespace:=cam0',
            'use_sim_time:=true', 'dataset:=shapes_rotation']
    tmp = tmp_path / 'tmp'   # where the launch file writes the namespaced parameter files
    tmp.mkdir()
    with started(args, log, dict(os.environ, TMPDIR=str(tmp))) as proc:
        # two nodes start and two namespaced parameter files are written: on a loaded
        # machine their discovery once took more than a minute (a full-suite run)
        wait_for('the namespaced packetizer', lambda: param('/cam0/packetizer_node',
                                                             'sensor_width')
                 == 'Integer value is: 240',  # from the config's packetizer_node section
                 timeout=150, log=log)
        assert param('/cam0/resonator_node', 'cleanup.gamma') == 'Double value is: 0.9'
        assert param('/cam0/resonator_node', 'use_sim_time') == 'Boolean value is: True'
        assert param('/cam0/packetizer_node', 'use_sim_time') == 'Boolean value is: True'
        # the relative topics and the frames remap land in the namespace
        wait_for('the namespaced frames link',
                 lambda: counts('/cam0/packetizer_node/frames') == (1, 1))
        wait_for('the namespaced events subscription',
                 lambda: counts('/cam0/event_camera/events')[1] == 1)
        # the camera's CameraInfo: the packetizer's rectification, the resonator's focal length
        wait_for('the namespaced camera_info subscriptions',
                 lambda: counts('/cam0/event_camera/camera_info')[1] == 2)
        wait_for('the namespaced pose topic', lambda: '/cam0/resonator_node/pose' in topics())
        assert '/packetizer_node/frames' not in topics()
        assert proc.poll() is None, log.read_text()
        assert len(list(tmp.glob('hrn_vo_*.yaml'))) == 2
    # the launch removed its files when it stopped, and launch_ros wrote none of its own
    assert not [*tmp.glob('hrn_vo_*'), *tmp.glob('launch_params_*')], log.read_text()
