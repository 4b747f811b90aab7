"""Access to a sequence folder or its zip: members by name, ``meta.json``, sizes and counts."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
import json
from pathlib import Path
from typing import IO
import zipfile

from hrn_vo_ros.errors import DatasetError

DEFAULT_SENSOR_SIZE = (240, 180)
"""(width, height) of the DAVIS240C used by every Event Camera Dataset sequence."""

META_FILE = 'meta.json'
META_FORMAT = 'hrn_vo_ecd/1'
EVENTS_FILE = 'events.txt'
IMU_FILE = 'imu.txt'
GROUNDTRUTH_FILE = 'groundtruth.txt'
CALIB_FILE = 'calib.txt'


class SequenceSource:
    """A sequence folder or zip: opens members by name and names them in error messages."""

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)
        if '.partial' in self.path.name:
            msg = ('is an unfinished write (".partial" in its name): an interrupted writer left '
                   'it; delete it and write the sequence again')
            raise DatasetError(msg, path=self.path)
        self._zip: zipfile.ZipFile | None = None
        self._prefix = ''
        if self.path.is_dir():
            return
        if not self.path.exists():
            raise DatasetError('does not exist: give an Event Camera Dataset folder or its .zip',
                               path=self.path)
        if not zipfile.is_zipfile(self.path):
            msg = 'is neither a folder nor a zip file (corrupt or truncated zip?)'
            raise DatasetError(msg, path=self.path)
        try:
            self._zip = zipfile.ZipFile(self.path)
        except (zipfile.BadZipFile, OSError) as err:
            raise DatasetError(f'cannot open zip: {err}', path=self.path) from err
        names = set(self._zip.namelist())
        if EVENTS_FILE not in names:
            tops = {n.split('/', 1)[0] for n in names if n.count('/') >= 1}
            hits = [t for t in sorted(tops) if f'{t}/{EVENTS_FILE}' in names]
            if len(hits) == 1:
                self._prefix = hits[0] + '/'

    def where(self, name: str) -> Path:
        """The path to name in messages (``seq.zip/events.txt`` for zip members)."""
        return self.path / (self._prefix + name)

    def exists(self, name: str) -> bool:
        """Whether the member ``name`` exists."""
        if self._zip is None:
            return (self.path / name).is_file()
        try:
            self._zip.getinfo(self._prefix + name)
        except KeyError:
            return False
        return True

    def size(self, name: str) -> int:
        """Uncompressed size of the member ``name`` in bytes."""
        if self._zip is None:
            return (self.path / name).stat().st_size
        return self._zip.getinfo(self._prefix + name).file_size

    @contextmanager
    def open(self, name: str) -> Iterator[IO[bytes]]:
        """The member as a binary stream; a missing member raises DatasetError."""
        if not self.exists(name):
            raise DatasetError(f'missing {name} (an Event Camera Dataset sequence has events.txt, '
                               'imu.txt, groundtruth.txt and calib.txt)', path=self.where(name))
        if self._zip is None:
            with open(self.path / name, 'rb') as f:
                yield f
        else:
            with self._zip.open(self._prefix + name) as f:
                yield f

    def read_text(self, name: str) -> str:
        """The whole member as ASCII text."""
        with self.open(name) as f:
            data = read_all(f, self.where(name))
        try:
            return data.decode('ascii')
        except UnicodeDecodeError as err:
            raise DatasetError(f'not ASCII text (byte {err.start}): is this the right file?',
                               path=self.where(name)) from err

    def close(self) -> None:
        """Close the zip file (nothing to do for a folder)."""
        if self._zip is not None:
            self._zip.close()

    def __enter__(self) -> SequenceSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_all(f: IO[bytes], where: Path, size: int = -1) -> bytes:
    """``f.read(size)``; a corrupt or truncated archive raises DatasetError naming ``where``."""
    try:
        return f.read(size)
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as err:
        raise DatasetError(f'cannot read (corrupt or truncated archive?): {err}',
                           path=where) from err


def read_meta(src: SequenceSource) -> dict[str, object]:
    """The ``meta.json`` of a sequence written by this package, or ``{}`` when absent."""
    if not src.exists(META_FILE):
        return {}
    try:
        meta = json.loads(src.read_text(META_FILE))
    except json.JSONDecodeError as err:
        raise DatasetError(f'invalid JSON: {err}', path=src.where(META_FILE)) from err
    if not isinstance(meta, dict) or meta.get('format') != META_FORMAT:
        raise DatasetError(f'not a {META_FORMAT} metadata file', path=src.where(META_FILE))
    return meta


def meta_count(meta: dict[str, object], key: str) -> int | None:
    """The line count ``meta['counts'][key]``, or None when not recorded."""
    counts = meta.get('counts')
    if isinstance(counts, dict) and isinstance(counts.get(key), int):
        return int(counts[key])
    return None


def read_sensor_size(path: Path | str) -> tuple[int, int]:
    """The sensor (width, height): from ``meta.json`` if present, else 240 x 180 (DAVIS240C)."""
    with SequenceSource(path) as src:
        return source_sensor_size(src)


def source_sensor_size(src: SequenceSource) -> tuple[int, int]:
    """Like :func:`read_sensor_size`, for an opened source."""
    meta = read_meta(src)
    if not meta:
        return DEFAULT_SENSOR_SIZE
    w, h = meta.get('width'), meta.get('height')
    if not (isinstance(w, int) and isinstance(h, int) and 0 < w <= 65535 and 0 < h <= 65535):
        raise DatasetError(f'width/height {w!r}/{h!r} must be integers in 1..65535',
                           path=src.where(META_FILE))
    return w, h


def event_count(path: Path | str) -> int | None:
    """The number of events recorded in ``meta.json``, or None (plain dataset folders)."""
    with SequenceSource(path) as src:
        return meta_count(read_meta(src), 'events')


def estimate_event_count(path: Path | str) -> int:
    """The event count from ``meta.json``, else estimated from the size of ``events.txt`` and
    the mean line length of its first 256 kB (for progress bars on plain dataset folders)."""
    with SequenceSource(path) as src:
        exact = meta_count(read_meta(src), 'events')
        if exact is not None:
            return exact
        if not src.exists(EVENTS_FILE):
            raise DatasetError(f'missing {EVENTS_FILE}', path=src.where(EVENTS_FILE))
        with src.open(EVENTS_FILE) as f:
            head = read_all(f, src.where(EVENTS_FILE), 1 << 18)
        lines = max(head.count(b'\n'), 1)
        return round(src.size(EVENTS_FILE) * lines / max(len(head), 1))


def events_size(path: Path | str) -> int:
    """Size of ``events.txt`` in bytes (uncompressed), e.g. as a progress-bar total."""
    with SequenceSource(path) as src:
        if not src.exists(EVENTS_FILE):
            raise DatasetError(f'missing {EVENTS_FILE}', path=src.where(EVENTS_FILE))
        return src.size(EVENTS_FILE)
