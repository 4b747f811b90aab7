"""The nodes' process entry point (:func:`run`): init, spin, and a clean exit on Ctrl-C,
SIGTERM or external shutdown at any point, without a traceback."""

from __future__ import annotations

from collections.abc import Callable
import contextlib
import signal

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from hrn_vo_ros.errors import ConfigError


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


def _shut_down(node: Node | None) -> None:
    """Destroy the node and shut rclpy down, ignoring further stop signals meanwhile."""
    steps: list[Callable[[], object]] = [] if node is None else [node.destroy_node]
    steps.append(rclpy.try_shutdown)
    while steps:
        try:
            _ignore_stop_signals()
            steps[0]()
        except KeyboardInterrupt:   # a signal that came before the handlers were replaced
            continue                # the step was interrupted: run it again, now shielded
        except Exception as err:     # the clean-up goes on; logged
            rclpy.logging.get_logger('hrn_vo_ros').warning(f'during shutdown: {err!r}')
        steps.pop(0)


def run(make_node: Callable[[], Node], args: list[str] | None = None) -> int:
    """The Jazzy entry point: init, spin, shut down cleanly on Ctrl-C or external shutdown.

    A :class:`ConfigError` while the node starts (bad parameters) is logged and gives exit 2.
    SIGINT or SIGTERM at any point from here on — during start-up, spin or shutdown, once or
    repeatedly — ends the process promptly with exit 0 and no traceback: a signal during
    start-up stops it there (rclpy's handler shuts the context down, so whatever the node was
    creating fails; that failure is not reported as an error), and once shutting down further
    signals are ignored until the bounded clean-up is done (the process is ending: they
    stay ignored).
    """
    node = None
    code = 0
    initialised = False
    default_stop_signals()   # drop the import-time exit (hrn_vo_ros.nodes) before rclpy's own
    try:
        rclpy.init(args=args)
        initialised = True
        node = make_node()
        executor = _executor()
        if executor is not None:
            rclpy.spin(node, executor=executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ConfigError as err:
        rclpy.logging.get_logger('hrn_vo_ros').error(f'invalid parameters: {err}')
        code = 2
    except Exception:
        if not initialised or rclpy.ok():   # a real error, not a signal during start-up
            raise
    finally:
        _shut_down(node)
    return code
