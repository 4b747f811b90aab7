"""The crash-safe bag writer: ``DST.partial/<name>`` renamed to ``DST`` once complete."""

from __future__ import annotations

import os
from pathlib import Path
import shutil
from types import TracebackType

from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.storage_mcap import McapWriter

from hrn_vo_ros.errors import BagError
from hrn_vo_ros.io.bags.mcap import scan_mcap
from hrn_vo_ros.io.bags.types import Storage, STORAGES, typestore


def _check_target(dst: Path) -> Path:
    partial = dst.with_name(dst.name + '.partial')
    if dst.exists() or dst.is_symlink():
        raise BagError(f'{dst} exists already: choose another output or delete it')
    if partial.exists():
        raise BagError(f'{partial} is left from an interrupted write: delete it and retry')
    return partial


class BagWriter:
    """Writes a ROS 2 bag crash-safely (``DST.partial/<name>`` renamed to ``DST`` on success).

    Use as a context manager; on an exception (including Ctrl-C) the partial bag is deleted.

    Args:
        dst: The bag directory to create; must not exist.
        storage: ``'mcap'`` (default) or ``'sqlite3'``.

    Raises:
        BagError: if ``dst`` (or a stale ``dst.partial``) exists.
    """

    def __init__(self, dst: Path | str, *, storage: Storage = 'mcap') -> None:
        if storage not in STORAGES:
            raise BagError(f'unknown storage {storage!r}; use one of {", ".join(STORAGES)}')
        self.dst = Path(dst)
        self.partial = _check_target(self.dst)
        self.ts = typestore()
        self._writer = Writer(self.partial / self.dst.name, version=9,
                              storage_plugin=STORAGES[storage])
        self.counts: dict[str, int] = {}

    def __enter__(self) -> BagWriter:
        self.partial.mkdir(parents=True)
        try:
            self._writer.open()
        except BaseException:
            shutil.rmtree(self.partial, ignore_errors=True)
            raise
        return self

    def set_custom_data(self, key: str, value: str) -> None:
        """Store ``key: value`` in the bag metadata's ``custom_data`` (set before closing)."""
        self._writer.set_custom_data(key, value)

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            self._writer.__exit__(exc_type, exc, tb)
            if exc_type is None:
                for mcap in (self.partial / self.dst.name).glob('*.mcap'):
                    scan_mcap(mcap, patch=True)  # rosbags writes zero CRCs: fill them in
                if self.dst.exists():
                    raise BagError(f'{self.dst} appeared while writing: not overwriting it')
                os.rename(self.partial / self.dst.name, self.dst)
        finally:
            shutil.rmtree(self.partial, ignore_errors=True)

    def flush(self) -> None:
        """Close the pending MCAP chunk and hand the file's bytes to the operating system.

        Everything written before a flush survives a SIGKILL of the writing process as complete
        chunks of the ``.partial`` bag, which :func:`recover_bag` salvages. A no-op for sqlite3
        (rosbags commits its rows only when the bag is closed) and with nothing pending.
        """
        storage = self._writer.storage
        if isinstance(storage, McapWriter):
            if storage.chunk.bio.tell():
                storage.close_chunk()
            storage.bio.flush()

    def add_topic(self, topic: str, msgtype: str, qos: Qos) -> Connection:
        """Register a topic with its type (definition and hash from :func:`typestore`)."""
        self.counts[topic] = 0
        return self._writer.add_connection(topic, msgtype, typestore=self.ts,
                                           offered_qos_profiles=[qos])

    def write(self, conn: Connection, t_ns: int, raw: bytes | memoryview) -> None:
        """Write one serialised (CDR) message with bag time ``t_ns``."""
        self._writer.write(conn, t_ns, raw)
        self.counts[conn.topic] += 1

    def write_msg(self, conn: Connection, t_ns: int, msg: object) -> None:
        """Serialise ``msg`` (a typestore message object) and write it."""
        self.write(conn, t_ns, self.ts.serialize_cdr(msg, conn.msgtype))
