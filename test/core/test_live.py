"""The live odometry of resonator_node (core/live.py) with a scripted estimator, without ROS."""

from __future__ import annotations

from collections import Counter
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.events.stream import Note
from hrn_vo_ros.core.hrn.config import geometry, ResonatorConfig
from hrn_vo_ros.core.live import (
    camera_focal_px,
    FocalLength,
    Item,
    LiveOdometry,
    LiveSettings,
    sized_config,
    sized_resonator,
    Step,
)
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.odometry.odometry import OdometryConfig
from hrn_vo_ros.core.odometry.publish import GyroGate
from hrn_vo_ros.errors import HrnVoError

EYE = tuple(float(v) for v in np.eye(3).ravel())
IMAGE = np.zeros((6, 8), np.uint8)
MS = 1_000_000


class Scripted:
    """An estimator recording whether each step had a gyro increment."""

    factors = ('h', 'v', 'r')
    rejected_frames = 0
    limited_frames = 0
    hot_pixels = 3
    tracker = SimpleNamespace(distinct=12.54, relocalisations=4, gaps=7)
    gyro_bias = SimpleNamespace(b=np.radians([0.5, -0.25, 0.0]))

    def __init__(self, fail_at: int = -1, state: str = 'tracking') -> None:
        self.steps: list[tuple[int, bool]] = []
        self.fail_at = fail_at
        self.state = state
        self.resets: list[int] = []     # the number of steps at each reset

    def reset(self) -> None:
        self.resets.append(len(self.steps))

    def step(self, image: Any, t_ns: int, *, gyro_delta: Any = None) -> Estimate:
        self.steps.append((t_ns, gyro_delta is not None))
        if len(self.steps) - 1 == self.fail_at:
            raise HrnVoError('diverged')
        return Estimate(t_ns, float(len(self.steps)), 0.0, 0.0, 0.0,
                        confidence={'h': 1.0, 'v': 1.0, 'r': 1.0},
                        quality=1.0 if self.state == 'tracking' else 0.0, state=self.state)


def settings(imu: bool = False, focal_px: float = 0.0, adopt: bool = False) -> LiveSettings:
    return LiveSettings(adopt_size=adopt, imu=imu, with_z=False,
                        odometry=OdometryConfig(focal_length_px=80.0), focal_px=focal_px,
                        lost_variance=1e6, min_quality=0.05, imu_timeout_s=0.5,
                        camera_from_imu=EYE)


def live(est: Scripted, now: list[float] | None = None, resize: Any = None) -> LiveOdometry:
    clock = now if now is not None else [0.0]
    gate = GyroGate(EYE, max_samples=1000, max_pending=3)
    return LiveOdometry(est, gate, (8, 6), tolerance_ns=10 * MS,  # type: ignore[arg-type]
                        resize=resize, counts=Counter(), now=lambda: clock[0])


def steps(items: list[Item]) -> list[int]:
    return [i.t_ns for i in items if isinstance(i, Step)]


def notes(items: list[Item]) -> list[tuple[str, str]]:
    return [(i.level, i.kind) for i in items if isinstance(i, Note)]


def test_without_imu_each_frame_is_one_step_with_a_twist_from_the_second() -> None:
    est = Scripted()
    lo = live(est)
    first = list(lo.frame(10**9, IMAGE, settings()))
    second = list(lo.frame(10**9 + 10 * MS, IMAGE, settings()))
    assert steps(first) == [10**9] and steps(second) == [10**9 + 10 * MS]
    assert isinstance(first[0], Step) and first[0].out.twist is None
    assert isinstance(second[0], Step) and second[0].out.twist is not None
    assert lo.counts['estimates_out'] == 2 and lo.counts['invalid_frames'] == 0
    assert [g for _, g in est.steps] == [False, False]


def test_with_imu_frames_wait_for_the_gyro_and_use_it() -> None:
    est = Scripted()
    lo = live(est)
    s = settings(imu=True)
    assert list(lo.frame(100 * MS, IMAGE, s)) == []
    assert steps(list(lo.imu(50 * MS, np.zeros(3), s))) == []
    assert steps(list(lo.imu(120 * MS, np.zeros(3), s))) == [100 * MS]
    assert list(lo.frame(200 * MS, IMAGE, s)) == []
    assert steps(list(lo.imu(250 * MS, np.zeros(3), s))) == [200 * MS]
    assert est.steps[1] == (200 * MS, True)           # the second has a gyro increment


def test_a_size_mismatch_is_a_reject_and_an_error_for_the_window() -> None:
    now = [5.0]
    lo = live(Scripted(), now)
    items = list(lo.frame(10**9, np.zeros((6, 9), np.uint8), settings()))
    assert notes(items) == [('reject', 'size')]
    assert lo.states(10.0)[0][0] == 'error' and 'frames are 9x6' in lo.states(10.0)[0][1]
    now[0] += 11.0
    assert lo.states(10.0) == [('ok', 'tracking tracking (quality 1.00)')]


def test_queue_drops_warn_for_the_window_after_the_callers_own_states() -> None:
    now = [5.0]
    lo = live(Scripted(), now)
    items = list(lo.queue_drops(28, 10))
    assert notes(items) == [('warn', 'frames_dropped')] and items[0].throttled
    text = ('28 frames dropped before the resonator: it falls behind the frames '
            '(queue frames_depth 10, oldest dropped first)')
    tracking = ('ok', 'tracking tracking (quality 1.00)')
    assert lo.states(10.0) == [tracking, ('warn', text)]
    assert lo.states(10.0, ('warn', 'no focal')) == [tracking, ('warn', 'no focal'),
                                                     ('warn', text)]
    now[0] += 11.0
    assert lo.states(10.0) == [tracking]


def test_adopting_sizes_builds_a_resonator_per_new_size_or_rejects_with_the_reason() -> None:
    """adopt_size: a 9x6 frame asks the resizer once and goes to the new resonator (the old
    one sees no more frames); back to 8x6, another; a refused size is a throttled warning
    and the usual reject (ERROR); without adopt_size the resizer is never asked."""
    first, built, asked = Scripted(), [], []

    def resize(width: int, height: int) -> tuple[Scripted | None, str]:
        asked.append((width, height))
        if width > 9:
            return None, f'cannot take {width}x{height}'
        built.append(Scripted())
        return built[-1], f'takes {width}x{height}'

    lo = live(first, resize=resize)
    assert steps(list(lo.frame(10**9, IMAGE, settings(adopt=True)))) == [10**9]
    wide = np.zeros((6, 9), np.uint8)
    assert notes(list(lo.frame(10**9 + MS, wide, settings()))) == [('reject', 'size')]
    assert asked == []                                   # not adopting: no resonator built
    items = list(lo.frame(10**9 + 2 * MS, wide, settings(adopt=True)))
    assert notes(items) == [('warn', 'frame_size')] and steps(items) == [10**9 + 2 * MS]
    assert [i.text for i in items if isinstance(i, Note)] == ['takes 9x6']
    items = list(lo.frame(10**9 + 3 * MS, wide, settings(adopt=True)))
    assert notes(items) == [] and lo.size == (9, 6) and asked == [(9, 6)]
    list(lo.frame(10**9 + 4 * MS, IMAGE, settings(adopt=True)))
    assert asked == [(9, 6), (8, 6)] and len(built) == 2
    assert [len(e.steps) for e in (first, *built)] == [1, 2, 1]
    items = list(lo.frame(10**9 + 5 * MS, np.zeros((6, 10), np.uint8), settings(adopt=True)))
    assert notes(items) == [('warn', 'frame_size_refused'), ('reject', 'size')]
    assert [i.throttled for i in items if isinstance(i, Note)] == [True, False]
    assert lo.size == (8, 6) and lo.states(10.0)[0][0] == 'error'


def test_frame_stamps_going_back_restart_the_time_state() -> None:
    est = Scripted()
    lo = live(est)
    s = settings(imu=True)
    list(lo.imu(10**9, np.zeros(3), s))
    list(lo.frame(2 * 10**9, IMAGE, s))                     # waits: not covered
    old_gyro = lo.gate.gyro
    assert notes(list(lo.frame(2 * 10**9 - 5 * MS, IMAGE, s))) == [('reject', 'time_backwards')]
    items = list(lo.frame(10**9 // 2, IMAGE, s))          # back by 1.5 s: a reset
    assert steps(items) == [2 * 10**9]                      # the waiting frame went first
    assert ('warn', 'time_reset') in notes(items)
    note = [i for i in items if isinstance(i, Note)][0]
    assert note.throttled and note.text.startswith('frames stamps went back')
    assert lo.counts['clock_resets_frames'] == 1 and lo.gate.gyro is not old_gyro
    assert lo.pipeline.gyro is lo.gate.gyro and lo.states(10.0)[-1][0] == 'warn'
    assert len(lo.gate) == 1
    # tracking restarts after the waiting frame (a new map from the first frame after the jump)
    assert est.resets == [1] and lo.counts['tracking_restarts'] == 1
    assert note.text.endswith('tracking restarts from the next frame')


def test_imu_stamps_and_frame_checks() -> None:
    est = Scripted()
    lo = live(est)
    s = settings(imu=True)
    list(lo.imu(10**9, np.zeros(3), s))
    assert notes(list(lo.imu(10**9, np.zeros(3), s))) == [('reject', 'imu_time')]
    list(lo.imu(10**8, np.zeros(3), s))
    assert lo.counts['clock_resets_imu'] == 1
    assert est.resets == []             # an IMU reset keeps tracking
    assert notes(list(lo.imu_frame('imu', 'imu_link'))) == [('warn', 'imu_frame')]
    assert list(lo.imu_frame('imu_link', 'imu_link')) == []
    assert lo.counts['imu_frame_mismatch'] == 1


def test_tick_processes_frames_when_the_imu_stopped() -> None:
    now = [0.0]
    lo = live(Scripted(), now)
    s = settings(imu=True)
    list(lo.frame(10**9, IMAGE, s))
    now[0] = 0.4
    assert list(lo.tick(s)) == []
    now[0] = 0.6
    assert steps(list(lo.tick(s))) == [10**9]


def test_tracking_errors_are_rejects_and_focal_warnings_notes() -> None:
    lo = live(Scripted(fail_at=0))
    assert notes(list(lo.frame(10**9, IMAGE, settings()))) == [('reject', 'tracking')]
    items = list(lo.frame(10**9 + MS, IMAGE, settings(focal_px=100.0)))
    assert notes(items) == [('warn', 'focal')] and isinstance(items[1], Step)
    assert items[1].odometry.focal_length_px == 100.0
    frames, extra = lo.static_frames(settings(focal_px=100.0), base='b', camera='c', imu='')
    assert extra == [] and [(p, c) for p, c, _, _ in frames] == [('b', 'c')]


def test_invalid_frames_and_both_clocks_resets_are_counted() -> None:
    """A frame the estimator could not use (valid False) counts once in invalid_frames; the
    diagnostics' clock_resets add the frames' and the IMU's resets."""
    class Blank(Scripted):
        def step(self, image: Any, t_ns: int, *, gyro_delta: Any = None) -> Estimate:
            est = super().step(image, t_ns, gyro_delta=gyro_delta)
            return Estimate(est.t_ns, est.h, est.v, est.r, est.z, valid=len(self.steps) != 2,
                            confidence=est.confidence, quality=est.quality, state=est.state)
    lo = live(Blank())
    s = settings(imu=True)
    list(lo.imu(10**9, np.zeros(3), s))
    list(lo.imu(10**8, np.zeros(3), s))                    # an IMU reset
    list(lo.imu(2 * 10**8, np.zeros(3), s))
    for t in (1, 2, 3):
        list(lo.frame(t * 10**8 + 10**7, IMAGE, settings()))
    list(lo.frame(10**7, IMAGE, settings()))                 # frames back by 0.3 s: a reset
    assert lo.counts['estimates_out'] == 4 and lo.counts['invalid_frames'] == 1
    assert dict(lo.diagnostic_values('1.0', 0, 0))['clock_resets'] == 2


def test_diagnostic_values_keys() -> None:
    lo = live(Scripted())
    list(lo.frame(10**9, IMAGE, settings()))
    values = dict(lo.diagnostic_values('1.0', 2, 1))
    assert values['output_subscribers'] == 2 and values['odom_subscribers'] == 1
    assert values['pending_frames'] == 0 and values['imu_rejected_frames'] == 0
    assert values['imu_limited_frames'] == 0
    assert values['hot_pixels'] == 3 and values['distinctiveness'] == '12.5'
    assert values['relocalisations'] == 4 and values['gaps'] == 7
    assert values['gyro_bias_deg_s'] == '+0.500 -0.250 +0.000'
    assert values['quality'] == '1.000' and values['clock_resets'] == 0
    assert list(values)[0] == 'frame_rate_hz'


def test_the_frames_structure_is_a_running_mean_and_explains_a_loss_on_noise() -> None:
    """A 6x8 frame with a row of three on pixels and a lone one: 2 neighbouring pairs where 4
    random pixels give 82 * 4 * 3 / (48 * 47) = 0.436 (ratio 4.585); a checkerboard has none
    (0): the running mean goes 4.585 -> 4.585 + 0.1 (0 - 4.585) = 4.127; an empty frame leaves
    it. A lost track on frames that scattered says why; on structured frames, or while
    tracking, it does not."""
    edges = np.zeros((6, 8), np.uint8)
    edges[1, 2:5] = 1
    edges[4, 6] = 1
    checker = (np.indices((6, 8)).sum(axis=0) % 2).astype(np.uint8)
    lo = live(Scripted(state='lost'))
    assert dict(lo.diagnostic_values('1.0', 0, 0))['frame_structure'] == 'nan'
    list(lo.frame(10**9, edges, settings()))
    assert lo.structure == pytest.approx(2 / (82 * 12 / (48 * 47)))
    list(lo.frame(10**9 + 10 * MS, IMAGE, settings()))
    assert lo.structure == pytest.approx(4.585, abs=1e-3)
    assert lo.states(10.0) == [('error', 'tracking lost (quality 0.00)')]
    list(lo.frame(10**9 + 20 * MS, checker, settings()))
    assert dict(lo.diagnostic_values('1.0', 0, 0))['frame_structure'] == '4.13'
    for k in range(30):
        list(lo.frame(10**9 + (30 + 10 * k) * MS, checker, settings()))
    assert lo.structure == pytest.approx(4.127 * 0.9**30, rel=1e-3)
    assert lo.states(10.0) == [('error', 'tracking lost (quality 0.00); the frames are as '
                                'scattered as noise (structure 0.17 < 1.5): a blank view, or a '
                                'noisy sensor')]
    tracking = live(Scripted())
    for k in range(30):
        list(tracking.frame(10**9 + 10 * k * MS, checker, settings()))
    assert tracking.states(10.0) == [('ok', 'tracking tracking (quality 1.00)')]


def test_sized_config_follows_the_frames_or_says_why_not() -> None:
    """frame_size: frames: a 4/3 canvas follows the frame (139x104 -> ceil(185.3) x
    ceil(138.7) = 186x139) and the text names the 2.1x pixels; a fixed 100x80 canvas
    cannot take 128x96 frames."""
    cfg, text = sized_config(ResonatorConfig(), 139, 104)
    assert cfg is not None and (cfg.width, cfg.height) == (139, 104)
    g = geometry(cfg)
    assert (g.canvas_width, g.canvas_height) == (186, 139)
    assert 'frames are 139x104: the resonator takes that size' in text and '2.1x' in text
    assert 'x the pixels' not in sized_config(ResonatorConfig(), 64, 48)[1]
    fixed = from_dict(ResonatorConfig, {'codebook': {'canvas_width': 100, 'canvas_height': 80}})
    none, why = sized_config(fixed, 128, 96)
    assert none is None and 'cannot take that size' in why


def test_rebuild_keeps_an_adopted_size_the_config_can_take_else_its_own() -> None:
    """A reconfiguration at the adopted 139x104 builds a 139x104 resonator; a config with a
    fixed 100x80 canvas cannot take it and is built at its own 96x72 (frames of 139x104 are
    then rejected); sized_resonator builds nothing for a size the config refuses."""
    made: list[ResonatorConfig] = []

    def make(cfg: ResonatorConfig) -> Any:
        made.append(cfg)
        return Scripted()

    lo = live(Scripted())
    lo.reconfigured(Scripted(), (139, 104))                       # type: ignore[arg-type]
    lo.rebuild(ResonatorConfig(), make)
    assert (made[-1].width, made[-1].height) == (139, 104) and lo.size == (139, 104)
    fixed = from_dict(ResonatorConfig, {'codebook': {'canvas_width': 100, 'canvas_height': 80}})
    lo.rebuild(fixed, make)
    assert (made[-1].width, made[-1].height) == (96, 72) and lo.size == (96, 72)
    assert notes(list(lo.frame(10**9, np.zeros((104, 139), np.uint8), settings()))) == [
        ('reject', 'size')]
    none, why = sized_resonator(fixed, 139, 104, make)
    assert none is None and 'cannot take that size' in why and len(made) == 2
    est, text = sized_resonator(ResonatorConfig(), 64, 48, make)
    assert isinstance(est, Scripted) and (made[-1].width, made[-1].height) == (64, 48)
    assert 'frames are 64x48: the resonator takes that size' in text


def test_camera_focal_length_in_frame_pixels_by_hand() -> None:
    """fx / D with D the binning factor the packetizer used, read off the two sizes."""
    assert camera_focal_px((199.09, (240, 180)), (96, 72)) == 199.09 / 2.5
    assert camera_focal_px((500.0, (640, 480)), (96, 72)) == 75.0           # D 6.667
    assert camera_focal_px((1000.0, (1280, 720)), (96, 54)) == 75.0         # D 13.33, 16:9
    assert camera_focal_px((250.0, (346, 260)), (96, 72)) == 250.0 / (260 / 72)   # auto 3.611
    assert camera_focal_px((250.0, (346, 260)), (139, 104)) == 100.0        # fixed 2.5
    assert camera_focal_px((100.0, (64, 48)), (64, 48)) == 100.0            # no binning


def test_focal_length_source_order_and_what_it_changes() -> None:
    rot = from_dict(ResonatorConfig, {'imu': {'enabled': True}})
    odo = OdometryConfig(focal_length_px=79.6)
    f = FocalLength()
    assert f.value(0.0, (96, 72)) == (0.0, 'odometry.focal_length_px')
    assert f.diagnostic_values(0.0, (96, 72), odo) == [
        ('focal_px', '79.6'), ('focal_source', 'odometry.focal_length_px')]
    assert f.odometry(odo, 0.0, (96, 72)) is odo and f.config(rot, (96, 72)) is rot
    warn = f.missing(rot, '/cam/camera_info')
    assert warn is not None and 'imu.enabled needs focal_px' in warn
    assert warn.endswith('set focal_px or publish a camera_info on /cam/camera_info')
    assert f.missing(from_dict(ResonatorConfig, {}), '/x') is None      # nothing needs it
    rebuild, text = f.adopt((500.0, (640, 480)), rot, (96, 72))
    assert rebuild and text.startswith('focal length 75 frame px from camera_info (fx 500 on '
                                       '640x480, frames 96x72)')
    assert f.value(0.0, (96, 72)) == (75.0, 'camera_info') and f.missing(rot, '/x') is None
    assert f.diagnostic_values(0.0, (96, 72), odo) == [('focal_px', '75'),
                                                       ('focal_source', 'camera_info')]
    assert f.value(80.0, (96, 72)) == (80.0, 'focal_px')              # a set focal_px wins
    with_cam = f.odometry(odo, 0.0, (96, 72))
    assert with_cam.focal_length_px == 75.0 and f.odometry(odo, 0.0, (96, 72)) is with_cam
    assert f.odometry(odo, 0.0, (48, 36)).focal_length_px == 37.5       # another frame size
    assert f.odometry(odo, 80.0, (96, 72)) is odo
    assert f.config(rot, (96, 72)).focal_px == 75.0
    kept = from_dict(ResonatorConfig, {'imu': {'enabled': True}, 'focal_px': 80.0})
    assert f.config(kept, (96, 72)) is kept
    plain = FocalLength()
    assert plain.adopt((500.0, (640, 480)), from_dict(ResonatorConfig, {}), (96, 72))[0] is False


def test_live_odometry_owns_the_focal_length_a_camera_info_gives() -> None:
    """Before a camera_info: no focal length, the gyro config's WARN in the diagnostics, a
    rebuild unchanged. Adopting one (500 px on 640x480 for 8x6 frames: D 80, 6.25 px) rebuilds
    a gyro config with it, not a plain one; later rebuilds and a resize (16x12: 12.5 px) carry
    it, a set focal_px wins, and the odometry's focal length follows it."""
    made: list[ResonatorConfig] = []

    def make(cfg: ResonatorConfig) -> Any:
        made.append(cfg)
        return Scripted()

    rot = from_dict(ResonatorConfig, {'imu': {'enabled': True}})
    odo = OdometryConfig(focal_length_px=80.0)
    lo = live(Scripted())
    assert lo.focal_for(rot, odo) == (0.0, odo)
    values, states = lo.diagnostics(5.0, ('9.5', 1, 2), rot, odo, '/cam/camera_info')
    assert values[:5] == [('frame_rate_hz', '9.5'), ('pending_frames', 0), ('gyro_samples', 0),
                          ('output_subscribers', 1), ('odom_subscribers', 2)]
    assert values[-2:] == [('focal_px', '80'), ('focal_source', 'odometry.focal_length_px')]
    warn = [m for lv, m in states if lv == 'warn' and 'no focal length' in m]
    assert len(warn) == 1 and warn[0].endswith('a camera_info on /cam/camera_info')
    lo.rebuild(rot, make)
    assert made[-1].focal_px == 0.0
    assert 'restarts' not in lo.adopt_camera((500.0, (640, 480)), ResonatorConfig(), make)
    assert len(made) == 1                                   # nothing waited for it
    lo.focal.camera = None
    text = lo.adopt_camera((500.0, (640, 480)), rot, make)
    assert text.startswith('focal length 6.25 frame px') and text.endswith('restarts with it')
    assert len(made) == 2 and made[-1].focal_px == 6.25 and lo.size == (8, 6)
    focal, with_cam = lo.focal_for(rot, odo)
    assert focal == 6.25 and with_cam.focal_length_px == 6.25
    values, states = lo.diagnostics(5.0, ('9.5', 1, 2), rot, odo, '/cam/camera_info')
    assert values[-2:] == [('focal_px', '6.25'), ('focal_source', 'camera_info')]
    assert not any('no focal length' in m for _, m in states)
    lo.rebuild(rot, make)
    assert made[-1].focal_px == 6.25
    est, _ = lo.sized(rot, 16, 12, make)
    assert est is not None and (made[-1].width, made[-1].focal_px) == (16, 12.5)
    own = from_dict(ResonatorConfig, {'imu': {'enabled': True}, 'focal_px': 7.0})
    lo.rebuild(own, make)
    assert made[-1].focal_px == 7.0 and lo.focal_for(own, odo) == (7.0, odo)


def test_the_start_up_line_says_what_the_resonator_takes() -> None:
    rot = from_dict(ResonatorConfig, {'imu': {'enabled': True}})
    lo = live(Scripted())
    assert lo.describe(rot, adopt_size=False, camera_info_topic=None) == (
        '96x72 frames, factors h/v/r, IMU True')
    assert lo.describe(ResonatorConfig(), adopt_size=True, camera_info_topic='/cam/info') == (
        '96x72 frames (or the size of the frames), factors h/v/r, IMU False, focal length '
        'from the first camera_info on /cam/info (focal_px 0)')
