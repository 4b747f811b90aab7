"""The time limit of a stopping node process (:class:`StopLimit`), used by
:mod:`hrn_vo_ros.nodes.process`."""

from __future__ import annotations

import faulthandler
import threading
import weakref

from rclpy.context import Context
import rclpy.utilities

#: Seconds a node process may take to end once it is stopping (its context shut down by a
#: signal or externally, or its clean-up begun); then every thread's stack goes to stderr and
#: the process exits 1. ``ros2 launch`` kills a node 10 s after its SIGINT anyway (SIGTERM
#: after 5 s, SIGKILL 5 s later): this limit makes a stuck stop end as fast and say where.
STOP_LIMIT_S = 10.0
#: How often the watchdog thread looks at the context (seconds).
WATCH_PERIOD_S = 0.2


class StopLimit:
    """The time limit of a stopping process: armed when its clean-up begins, or by a daemon
    thread once the context is shut down; disarmed when
    :func:`~hrn_vo_ros.nodes.process.run` returns.

    A stop signal reaches rclpy's handler, which shuts the context down from its own thread and
    wakes the executor; should the main thread never get back to Python (stuck in a callback,
    or in rclpy's C code with the stop signals blocked), nothing would end the process. The
    limit is :func:`faulthandler.dump_traceback_later`, which needs neither the GIL nor the
    main thread to fire. It is process-wide: disarmed when ``run`` returns, it cannot end a
    caller that goes on (a test running a node in its own process).
    """

    def __init__(self, limit_s: float) -> None:
        self.limit_s = limit_s
        self._lock = threading.Lock()
        self._done = False
        self._quit = threading.Event()  # the watchdog thread ends (stop_watching, disarm)
        self._thread: threading.Thread | None = None

    def watch(self) -> None:
        """Start the thread that arms the limit once the (initialised) default context is no
        longer ok. It watches that context object, through a weak reference (the context is
        collected when ``run`` ends): ``rclpy.ok()`` after a shutdown would make a new default
        context, left alive past ``run``."""
        ref = weakref.ref(rclpy.utilities.get_default_context())
        self._thread = threading.Thread(target=self._watch, args=(ref,),
                                        name='hrn_vo_ros_stop_limit', daemon=True)
        self._thread.start()

    def _watch(self, ref: weakref.ref[Context]) -> None:
        while _ok(ref):
            if self._quit.wait(WATCH_PERIOD_S):
                return                  # the clean-up armed the limit itself, or run ended
        self.arm()

    def stop_watching(self) -> None:
        """End the watchdog thread and wait for it (at most a period): the clean-up, which
        armed the limit itself, then destroys the node and the context with no other thread
        touching rclpy (a node process was seen to crash in ``destroy_node`` at shutdown with
        the watchdog thread between two looks at the context)."""
        self._quit.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=2.0 * WATCH_PERIOD_S)

    def arm(self) -> None:
        """From now, ``limit_s`` to the end of ``run`` (again from now if armed)."""
        with self._lock:
            if not self._done:
                faulthandler.dump_traceback_later(self.limit_s, exit=True)

    def disarm(self) -> None:
        """For good: ``run`` is returning."""
        with self._lock:
            self._done = True
            faulthandler.cancel_dump_traceback_later()
        self._quit.set()


def _ok(ref: weakref.ref[Context]) -> bool:
    """Whether the referenced context still exists and is ok (no reference kept)."""
    context = ref()
    return context is not None and context.ok()
