"""Play a table on a device from Python: the library behind ``shapedisplay device upload|play``.

A :class:`DeviceSession` holds one :class:`~.host.DeviceLink` and does what
the commands do, in the same order and with the same messages:

* the table is read and verified here first (its checksum, its schema), so a
  damaged file is refused in one line before anything is sent;
* an upload is verified and committed by the device (:meth:`DeviceLink.upload
  <shapedisplay.link.host.DeviceLink.upload>`); :meth:`DeviceSession.play`
  uploads only when the table is not already the device's active one (same
  CRC-32 of the image);
* a stroke streams at the device's cursor rate, with backpressure; in
  ``mode="actuator"`` the host renders the drive and streams it;
* with ``record=PATH`` the drive the device played is saved as a *device
  recording* (:func:`write_recording`, read back by :func:`read_recording`),
  atomically.

The device recording is not the renderer's trace
(:func:`shapedisplay.render.sinks.write_trace`): a device reports the drive
of each tick it played and when it played it, not the pad's state, so the
file holds those alone.

Shortcuts for one operation on a port: :func:`upload` and :func:`play`.
Nothing here opens a port or imports pyserial at import time.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from shapedisplay.errors import FileFormatError, InputError

if TYPE_CHECKING:                      # pyserial and the renderer load on first use, not at import
    from shapedisplay.link.host import StreamReport, UploadReport
    from shapedisplay.table.model import FrictionTable

DEFAULT_TIMEOUT_S = 0.5
DEFAULT_RETRIES = 4
MODES = ("cursor", "actuator")
#: Entries of a device recording (.npz); see :func:`write_recording`.
RECORDING_ARRAYS = ("drive", "latency_s", "tick_rate_hz", "stream_rate_hz")
#: Most drive values (renderer ticks) a recording may hold when read back: an hour at 10 kHz.
MAX_RECORDING_TICKS = 36_000_000


@dataclass(frozen=True)
class TableImage:
    """A verified table and the bytes a device receives for it.

    Attributes
    ----------
    table : FrictionTable
        The table, read and checked (checksum, schema).
    image : bytes
        What is uploaded: the table file's bytes (.npz) or a binary table
        image (``export --format bin``), exactly as given.
    """

    table: FrictionTable
    image: bytes

    @property
    def crc32(self) -> int:
        """CRC-32 of :attr:`image`, the number a device reports for its active table."""
        from shapedisplay.link.framing import crc32
        return crc32(self.image)


def table_image(source) -> TableImage:
    """Read and verify the table a device is to play.

    Parameters
    ----------
    source : str, PathLike, FrictionTable, bytes or TableImage
        A table file (.npz) or binary table image on disk; a table in memory
        (its .npz bytes are uploaded); the bytes of either file kind.

    Raises
    ------
    TableError
        One line naming the defect (``checksum mismatch``, not a table, ...).
    """
    from shapedisplay.render.image import is_image, load_table_or_image, read_image
    from shapedisplay.table.model import FrictionTable
    if isinstance(source, TableImage):
        return source
    if isinstance(source, FrictionTable):
        return TableImage(source, source.to_bytes())
    if isinstance(source, (bytes, bytearray, memoryview)):
        data = bytes(source)
        table = read_image(data, "table image") if is_image(data) else FrictionTable.from_bytes(data, "table")
        return TableImage(table, data)
    if isinstance(source, (str, os.PathLike)):
        return TableImage(*load_table_or_image(source))
    raise InputError(f"table must be a path, a FrictionTable or the bytes of a table file "
                     f"(got {type(source).__name__})")


def check_record_path(path) -> None:
    """Refuse a recording path whose folder does not exist (before a stroke is played, not after)."""
    if path is None:
        return
    folder = Path(path).parent
    if not folder.is_dir():
        raise InputError(f"output '{path}': directory '{folder}' does not exist")


@dataclass
class PlayReport:
    """What :meth:`DeviceSession.play` did.

    Attributes
    ----------
    port : str
    mode : {"cursor", "actuator"}
    stream : StreamReport
        The device's counts for the stream (:class:`~.host.StreamReport`).
    upload : UploadReport or None
        The upload done first, None when the table was already active
        (or in actuator mode, which needs no table on the device).
    tick_rate_hz, stream_rate_hz : int
        The device's renderer tick rate and cursor sample rate, Hz.
    record : Path or None
        The device recording written, if one was asked for.
    """

    port: str
    mode: str
    stream: StreamReport
    upload: UploadReport | None = None
    tick_rate_hz: int = 0
    stream_rate_hz: int = 0
    record: Path | None = None

    @property
    def sent(self) -> int:
        """Cursor samples (or actuator blocks) sent."""
        return self.stream.sent

    @property
    def rendered(self) -> int:
        """Cursor samples the device rendered."""
        return self.stream.rendered

    @property
    def seconds(self) -> float:
        """Wall time of the stream, s."""
        return self.stream.seconds

    @property
    def overruns(self) -> int:
        """Samples the device dropped at a full queue."""
        return self.stream.overruns

    @property
    def drive(self) -> np.ndarray | None:
        """Drive of every renderer tick the device played, full scale 1.0 (recorded plays only)."""
        return self.stream.outputs

    @property
    def latencies_s(self) -> np.ndarray | None:
        """Per cursor sample: send to the device's OUTPUT received, s; NaN where it was lost (recorded plays)."""
        return self.stream.latencies_s

    def problems(self) -> list[str]:
        """One line per fault the device reported (:meth:`~.host.StreamReport.problems`)."""
        return self.stream.problems()


class DeviceSession:
    """One device on one port: upload tables and play strokes.

    Parameters
    ----------
    port : str
        Device path (``/dev/ttyACM0``, ``COM3``), a pty from ``shapedisplay
        device emulate``, or a pyserial URL (``socket://host:7000``).
    baudrate : int
        Line rate, bit/s (default 921600; ignored by ptys).
    timeout : float
        Seconds to wait for each reply before a resend (> 0).
    retries : int
        Resends of a request before giving up (>= 0).

    The port is opened and the device greeted on first use (:meth:`connect`,
    :attr:`caps`, or any operation), so the table and the recording path of
    a call are checked before anything is sent. Use it in a ``with`` block
    or call :meth:`close`.

    Examples
    --------
    >>> with DeviceSession("/dev/ttyACM0") as dev:                      # doctest: +SKIP
    ...     played = dev.play("tent.npz", "0,0 -> 60,0 @ 50 mm/s", record="played.npz")
    """

    def __init__(self, port: str, baudrate: int | None = None, timeout: float = DEFAULT_TIMEOUT_S,
                 retries: int = DEFAULT_RETRIES):
        from shapedisplay.link.host import DEFAULT_BAUD, DeviceLink
        self.port = port
        self.link = DeviceLink(port, baudrate=DEFAULT_BAUD if baudrate is None else baudrate,
                               timeout=timeout, retries=retries)

    # ------------------------------------------------------------ connection
    def connect(self):
        """Open the port and handshake if not done yet; return the device's :class:`~.protocol.Caps`."""
        if self.link.caps is None:
            try:
                self.link.connect()
            except BaseException:
                self.link.close()           # a failed handshake leaves no port open
                raise
        return self.link.caps

    @property
    def caps(self):
        """The device's capabilities (:class:`~.protocol.Caps`: memory in bytes, rates in Hz)."""
        return self.connect()

    def status(self):
        """The device's state and fault counters now (:class:`~.protocol.Status`)."""
        self.connect()
        return self.link.status()

    def close(self) -> None:
        """Close the port. Safe to call twice or after a failure."""
        self.link.close()

    def __enter__(self) -> "DeviceSession":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------ operations
    def upload(self, table, progress=None) -> UploadReport:
        """Upload ``table``, have the device verify it and make it active.

        Parameters
        ----------
        table : str, PathLike, FrictionTable, bytes or TableImage
            See :func:`table_image`; verified here before anything is sent.
        progress : callable, optional
            ``progress(done_bytes, total_bytes)`` after each acknowledged chunk.

        Returns
        -------
        UploadReport
            Size (bytes), CRC-32, chunks, repairs, seconds (:class:`~.host.UploadReport`).

        Raises
        ------
        TableError
            The table is damaged (nothing sent).
        DeviceRefused
            The image exceeds the device memory (nothing sent), or the device
            rejected it; the previous table stays active.
        """
        src = table_image(table)
        self.connect()
        return self.link.upload(src.image, progress=progress)

    def is_active(self, table) -> bool:
        """True if ``table`` is the device's active table (same image CRC-32)."""
        src = table_image(table)
        return self.status().active_crc == src.crc32

    def play(self, table, stroke, *, mode: str = "cursor", model: str = "jump", record=None,
             on_upload=None) -> PlayReport:
        """Play ``stroke`` over ``table`` on the device.

        Parameters
        ----------
        table : str, PathLike, FrictionTable, bytes or TableImage
            See :func:`table_image`. In cursor mode it is uploaded first unless
            it is already the device's active table.
        stroke : str or CursorPath
            A stroke in mm on the table grid, e.g. ``"0,0 -> 60,0 @ 50 mm/s"``
            or ``"0,2 <-> 60,2 @ 20 mm/s x3"`` (sampled at the device's cursor
            rate); or a :class:`~shapedisplay.render.cursor.CursorPath` in m
            whose ``tick_rate`` is the device's ``stream_rate_hz``.
        mode : {"cursor", "actuator"}
            cursor: the device renders (needs a renderer on the device);
            actuator: the host renders with ``model`` and streams the drive.
        model : str
            Renderer model of actuator mode (the device's own in cursor mode).
        record : str or PathLike, optional
            Write the drive the device played here (:func:`write_recording`);
            its folder is checked before anything is played.
        on_upload : callable, optional
            ``on_upload(UploadReport)`` once an upload is committed, before
            the stroke streams.

        Returns
        -------
        PlayReport
        """
        if mode not in MODES:
            raise InputError(f"`mode` must be one of {', '.join(MODES)} (got {mode!r})")
        src = table_image(table)
        check_record_path(record)
        caps = self.connect()
        if mode == "cursor" and not caps.has_renderer:
            raise InputError(f"device on '{self.port}' has no renderer; use --mode actuator")
        x, y = self._cursor(stroke, caps)
        uploaded = None
        if mode == "cursor" and self.link.status().active_crc != src.crc32:
            uploaded = self.link.upload(src.image)
            if on_upload is not None:
                on_upload(uploaded)
        monitor = record is not None
        if mode == "cursor":
            rep = self.link.stream(x, y, monitor=monitor)
        else:
            from shapedisplay.link.engine import actuator_blocks
            from shapedisplay.render import Renderer
            r = Renderer(src.table, model=model, tick_rate=float(caps.tick_rate_hz))
            blocks = actuator_blocks(r, x, y, caps.samples_per_cursor)
            rep = self.link.stream(blocks, mode="actuator", monitor=monitor)
        out = PlayReport(self.port, mode, rep, uploaded, caps.tick_rate_hz, caps.stream_rate_hz)
        if record is not None:
            out.record = write_recording(record, rep.outputs, rep.latencies_s, caps.tick_rate_hz,
                                         caps.stream_rate_hz)
        return out

    @staticmethod
    def _cursor(stroke, caps):
        """Cursor positions (m), one per device stream period, from a stroke text or a CursorPath."""
        from shapedisplay.render.cursor import CursorPath, parse_stroke
        rate = float(caps.stream_rate_hz)
        if isinstance(stroke, str):
            path = parse_stroke(stroke, rate)
        elif isinstance(stroke, CursorPath):
            if stroke.tick_rate is None or not math.isclose(stroke.tick_rate, rate):
                raise InputError(f"cursor path '{stroke.source}' is sampled at {stroke.tick_rate} Hz; the device "
                                 f"takes one sample per stream period ({caps.stream_rate_hz} Hz)")
            path = stroke
        else:
            raise InputError(f"stroke must be a stroke text or a CursorPath (got {type(stroke).__name__})")
        return path.x, path.y


# ------------------------------------------------------------------ shortcuts
def upload(table, port: str, *, baudrate: int | None = None, timeout: float = DEFAULT_TIMEOUT_S,
           retries: int = DEFAULT_RETRIES, progress=None) -> UploadReport:
    """Upload ``table`` to the device on ``port`` and close it; see :meth:`DeviceSession.upload`.

    ``baudrate`` in bit/s, ``timeout`` in seconds per reply, ``retries`` resends.
    Returns the :class:`~.host.UploadReport`.
    """
    src = table_image(table)
    with DeviceSession(port, baudrate, timeout, retries) as dev:
        return dev.upload(src, progress=progress)


def play(table, stroke, port: str, *, mode: str = "cursor", model: str = "jump", record=None, on_upload=None,
         baudrate: int | None = None, timeout: float = DEFAULT_TIMEOUT_S,
         retries: int = DEFAULT_RETRIES) -> PlayReport:
    """Play ``stroke`` over ``table`` on the device on ``port`` and close it; see :meth:`DeviceSession.play`.

    ``baudrate`` in bit/s, ``timeout`` in seconds per reply, ``retries`` resends.
    """
    with DeviceSession(port, baudrate, timeout, retries) as dev:
        return dev.play(table, stroke, mode=mode, model=model, record=record, on_upload=on_upload)


# ------------------------------------------------------------------ device recordings
def write_recording(path, drive, latency_s, tick_rate_hz: int, stream_rate_hz: int) -> Path:
    """Write a device recording (.npz, atomic; readable with ``numpy.load``).

    Parameters
    ----------
    path : str or PathLike
    drive : ndarray (m,), float
        Drive of every renderer tick the device played, in order, full scale
        1.0 (cursor mode: 1 + (n - 1) x ticks per cursor sample; actuator
        mode: n x ticks per cursor sample).
    latency_s : ndarray (n,), float
        Per cursor sample, from sending it to receiving its OUTPUT, s; NaN
        where that OUTPUT was lost on the line.
    tick_rate_hz, stream_rate_hz : int
        The device's renderer tick rate and cursor sample rate, Hz.

    Returns
    -------
    Path of the file written.
    """
    from shapedisplay.atomic import atomic_path
    arrays = {"drive": np.asarray(drive, dtype=np.float64).reshape(-1),
              "latency_s": np.asarray(latency_s, dtype=np.float64).reshape(-1),
              "tick_rate_hz": np.asarray(int(tick_rate_hz), dtype=np.int64),         # 0-d: int(z["..."])
              "stream_rate_hz": np.asarray(int(stream_rate_hz), dtype=np.int64)}
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    return Path(path)


def read_recording(path) -> dict:
    """Read a device recording written by :func:`write_recording`.

    Returns ``{"drive": ndarray, "latency_s": ndarray, "tick_rate_hz": int,
    "stream_rate_hz": int}``. The file goes through the bounded ``.npz``
    reader (at most :data:`MAX_RECORDING_TICKS` drive values).

    Raises :class:`FileFormatError` for a missing, foreign or damaged file.
    """
    from shapedisplay.table.container import NpzReader
    p = Path(path)
    label = f"device recording '{p}'"
    if not p.is_file():
        raise FileFormatError(f"{label}: no such file" if not p.exists() else f"{label}: is not a file")
    with NpzReader(p, label, None, max_entries=64, error=FileFormatError) as z:
        missing = [n for n in RECORDING_ARRAYS if n not in z]
        if missing:
            what = "a table" if "header" in z else "a render trace" if "t" in z else "a foreign .npz"
            raise FileFormatError(f"{label}: lacks {missing}; this is {what}, not a device recording")
        unknown = sorted(set(z.entries) - set(RECORDING_ARRAYS))
        if unknown:
            raise FileFormatError(f"{label}: unexpected entry '{unknown[0]}'; not a device recording")
        out = {"drive": z.read_array("drive", ("f8", "f4"), MAX_RECORDING_TICKS, ndim=1),
               "latency_s": z.read_array("latency_s", ("f8", "f4"), MAX_RECORDING_TICKS, ndim=1)}
        for n in ("tick_rate_hz", "stream_rate_hz"):
            out[n] = int(z.read_array(n, ("i8", "i4", "u4", "u2"), 1, shape=()).item())
    if not np.isfinite(out["drive"]).all():
        raise FileFormatError(f"{label}: 'drive' holds NaN or infinite values")
    for n in ("tick_rate_hz", "stream_rate_hz"):
        if out[n] <= 0:
            raise FileFormatError(f"{label}: '{n}' must be > 0 (got {out[n]})")
    return out
