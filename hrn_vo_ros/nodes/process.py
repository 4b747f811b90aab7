"""The nodes' process entry points: :func:`run` (init, spin) and :func:`run_task` (init, one
job, exit: ``bag_player``), each with a clean exit on Ctrl-C, SIGTERM or external shutdown at
any point, without a traceback, bounded in time."""

from __future__ import annotations

from collections.abc import Callable
import contextlib
import faulthandler
import gc
import signal
from typing import TypeVar

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from hrn_vo_ros.errors import ConfigError, HrnVoError
from hrn_vo_ros.nodes.stop_limit import STOP_LIMIT_S, StopLimit

N = TypeVar('N', bound=Node)


def _ignore_stop_signals() -> None:
    """From here on SIGINT and SIGTERM cannot interrupt the (short, bounded) clean-up.

    ``ros2 launch`` sends SIGINT to every process and escalates with SIGTERM; a user may press
    Ctrl-C twice. A second signal inside ``destroy_node`` would otherwise raise there (a
    traceback and exit -2) and leave e.g. the recorder's bag unfinished.
    """
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(ValueError, OSError):   # not the main thread: keep them
            signal.signal(sig, signal.SIG_IGN)


def _executor() -> SingleThreadedExecutor | None:
    """rclpy's executor, made with the stop signals held back until it exists; None when a
    signal already shut the context down (while the node was being made).

    An executor made on a shut-down context, or interrupted in its constructor, is left
    half-made and its ``__del__`` prints a traceback; held back, a signal arrives right after
    and stops the node as at any other point.
    """
    stop = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, stop)
    try:
        return SingleThreadedExecutor() if rclpy.ok() else None
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def default_stop_signals() -> None:
    """SIGINT raises KeyboardInterrupt and SIGTERM ends the process again (Python's defaults),
    replacing the start-up handlers of :mod:`hrn_vo_ros.nodes`; ``rclpy.init`` then installs
    its own handlers on top, as in any rclpy program."""
    with contextlib.suppress(ValueError, OSError):   # not the main thread: keep them
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _shielded(steps: list[Callable[[], object]]) -> None:
    """Run clean-up ``steps`` in order with the stop signals ignored: a step that a signal
    interrupted before they were ignored runs again; an error is logged and the rest go on."""
    while steps:
        try:
            _ignore_stop_signals()
            steps[0]()
        except KeyboardInterrupt:   # a signal that came before the handlers were replaced
            continue                # the step was interrupted: run it again, now shielded
        except Exception as err:     # the clean-up goes on; logged
            rclpy.logging.get_logger('hrn_vo_ros').warning(f'during shutdown: {err!r}')
        steps.pop(0)


def _shut_down(node: Node | None, limit: StopLimit | None = None) -> None:
    """Arm the stop ``limit`` and end its watchdog thread, destroy the node and shut rclpy
    down, ignoring further stop signals meanwhile."""
    steps: list[Callable[[], object]] = [] if limit is None else [limit.arm,
                                                                  limit.stop_watching]
    steps += [] if node is None else [node.destroy_node]
    steps.append(rclpy.try_shutdown)
    _shielded(steps)


def run(make_node: Callable[[], Node], args: list[str] | None = None,
        stop_limit_s: float = STOP_LIMIT_S) -> int:
    """The Jazzy entry point: init, spin, shut down cleanly on Ctrl-C or external shutdown.

    A :class:`ConfigError` while the node starts (bad parameters) is logged and gives exit 2.
    SIGINT or SIGTERM at any point from here on — during start-up, spin or shutdown, once or
    repeatedly — ends the process promptly with exit 0 and no traceback: a signal during
    start-up stops it there (rclpy's handler shuts the context down, so whatever the node was
    creating fails; that failure is not reported as an error), and once shutting down further
    signals are ignored until the bounded clean-up is done (the process is ending: they
    stay ignored). A stop that takes longer than ``stop_limit_s`` from the context's shutdown
    or the clean-up's start (:data:`STOP_LIMIT_S`) dumps every thread's stack to stderr and
    exits 1: a hang is bounded and says where it was.
    """
    return _entry(make_node, _spin, args, interrupted=0, errors=ConfigError,
                  prefix='invalid parameters: ', logger='hrn_vo_ros', stop_limit_s=stop_limit_s)


def run_task(make_node: Callable[[], N], task: Callable[[N], int],
             args: list[str] | None = None, *, interrupted: int = 130,
             logger: str = 'hrn_vo_ros', stop_limit_s: float = STOP_LIMIT_S) -> int:
    """The entry point of a node that does one job and exits (``bag_player``): init, make the
    node, ``task(node)``'s exit code.

    Ctrl-C, SIGTERM or an external shutdown during the job give ``interrupted`` (130, as a
    shell reports Ctrl-C), as does an error raised because the context was shut down; a
    :class:`~hrn_vo_ros.errors.HrnVoError` is logged (``logger``) and gives its ``exit_code``.
    The clean-up is :func:`run`'s: shielded from further stop signals and bounded by
    ``stop_limit_s`` (a stack dump and exit 1 beyond it).
    """
    return _entry(make_node, task, args, interrupted=interrupted, errors=HrnVoError, prefix='',
                  logger=logger, stop_limit_s=stop_limit_s)


def _spin(node: Node) -> int:
    """:func:`run`'s job: spin until shut down (not at all when a signal came first)."""
    executor = _executor()
    if executor is not None:
        try:
            rclpy.spin(node, executor=executor)
        finally:
            # Its guard conditions (one registered with rclpy's signal handler) go now, while
            # the node and context live, not whenever the garbage collector reaches the
            # executor's reference cycle (possibly at the interpreter's exit).
            _shielded([executor.shutdown])
    return 0


def _entry(make_node: Callable[[], N], task: Callable[[N], int], args: list[str] | None, *,
           interrupted: int, errors: type[HrnVoError], prefix: str, logger: str,
           stop_limit_s: float) -> int:
    """Both entry points: init, make the node, ``task(node)``'s code; a stop signal (or an
    error it caused) gives ``interrupted``, an ``errors`` exception is logged and gives its
    ``exit_code``, any other error is raised; the clean-up shielded and time-bounded."""
    node: N | None = None
    code = 0
    initialised = False
    limit = StopLimit(stop_limit_s)
    faulthandler.enable()    # a crash in C (rclpy, the DDS) prints every thread's stack first
    default_stop_signals()   # drop the import-time exit (hrn_vo_ros.nodes) before rclpy's own
    try:
        rclpy.init(args=args)
        initialised = True
        limit.watch()
        node = make_node()
        code = task(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = interrupted
    except errors as err:
        rclpy.logging.get_logger(logger).error(f'{prefix}{err}')
        code = err.exit_code
    except Exception:
        if not initialised or rclpy.ok():   # a real error, not the consequence of a signal
            raise
        code = interrupted
    finally:
        _shut_down(node, limit)
        # The last rclpy objects (the node and its context, kept by reference cycles through
        # their callbacks) go now, while the interpreter is whole, not in its finalization.
        node = None
        _shielded([gc.collect])
        limit.disarm()          # the stop signals stay ignored: nothing interrupts this
    return code
