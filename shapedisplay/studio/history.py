"""The studio's undo history of the scene file: every version's exact bytes, kept under the output folder.

A step is one change of the file: ``{label, before, after, time}``, where
``before`` and ``after`` name stored versions (:func:`~shapedisplay.studio.edits.version_of`
of the bytes; each version is stored once, as ``blobs/VERSION.toml``). Undo
writes the ``before`` bytes back, redo the ``after`` bytes: byte for byte what
the file held. Changes made outside the studio (another editor) become steps
too, the next time the studio looks at the file (:meth:`History.sync`), so that
undo always steps back from what is on disk.

The history lives in ``OUT/history-STEM/`` (``index.json`` and ``blobs/``):
it outlives a reload of the page and a restart of the studio. It is bounded:
at most :data:`MAX_STEPS` steps and :data:`MAX_BYTES` of stored versions; the
oldest steps go first.
"""
from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

from shapedisplay.errors import InputError
from shapedisplay.studio.edits import version_of

#: Most steps kept (the oldest are dropped).
MAX_STEPS = 200
#: Most bytes of stored versions kept (the oldest steps are dropped until the rest fit).
MAX_BYTES = 64 << 20


def _write(path: Path, data: bytes) -> None:
    """Replace ``path`` by ``data`` in one rename (not flushed to disk: the scene file itself is; a
    history lost to a power cut costs the steps, never the file)."""
    tmp = path.with_name(f".{path.name}.part")
    tmp.write_bytes(data)
    os.replace(tmp, path)


class History:
    """Undo / redo steps of one scene file, stored in ``folder``."""

    def __init__(self, folder: Path, max_steps: int = MAX_STEPS, max_bytes: int = MAX_BYTES):
        self.folder = Path(folder)
        self.blobs = self.folder / "blobs"
        self.max_steps, self.max_bytes = max_steps, max_bytes
        self.lock = threading.RLock()
        self.steps: list = []
        self.position = 0                  # steps[:position] are applied
        self.head: str | None = None       # the version the history last saw on disk
        self.opened: str | None = None     # the version when this studio started (revert to it)
        self.sizes: dict = {}              # version -> bytes of its stored copy
        self.seen: dict = {}               # versions seen but not yet stored (no step needs them yet)
        index = self.folder / "index.json"
        try:
            d = json.loads(index.read_text(encoding="utf-8"))
            steps = d.get("steps", [])
            if all(isinstance(s, dict) and {"label", "before", "after"} <= set(s) for s in steps):
                self.steps = steps
                self.position = min(max(int(d.get("position", len(steps))), 0), len(steps))
                self.head = d.get("head")
        except (OSError, ValueError, TypeError):
            pass

    # -------------------------------------------------------------- storage
    def _store(self, data: bytes) -> str:
        v = version_of(data)
        p = self.blobs / f"{v}.toml"
        if not p.is_file():
            self.blobs.mkdir(parents=True, exist_ok=True)
            _write(p, data)
        return v

    def blob(self, version: str | None) -> bytes | None:
        """The stored bytes of ``version`` (None if it was never seen or has been dropped)."""
        if not isinstance(version, str) or not version.isalnum():
            return None
        if version in self.seen:
            return self.seen[version]
        try:
            return (self.blobs / f"{version}.toml").read_bytes()
        except OSError:
            return None

    def _save(self) -> None:
        """Note that the index changed; :meth:`flush` writes it (the studio calls it once the new table
        is on its way, so that writing the index is not in the designer's wait)."""
        self._prune()
        self.dirty = True

    def flush(self) -> None:
        """Write the index if it changed."""
        with self.lock:
            if not getattr(self, "dirty", False):
                return
            self.folder.mkdir(parents=True, exist_ok=True)
            _write(self.folder / "index.json", json.dumps(
                {"head": self.head, "position": self.position, "steps": self.steps}, indent=1).encode())
            self.dirty = False

    def _size(self, v: str) -> int:
        if v not in self.sizes:
            try:
                self.sizes[v] = (self.blobs / f"{v}.toml").stat().st_size
            except OSError:
                self.sizes[v] = 0
        return self.sizes[v]

    def _prune(self) -> None:
        """Drop the oldest steps beyond the bounds, and the stored versions no step needs any more."""
        dropped = False
        while len(self.steps) > self.max_steps or (
                len(self.steps) > 1 and sum(self._size(v) for v in self._live()) > self.max_bytes):
            self.steps.pop(0)
            self.position = max(self.position - 1, 0)
            dropped = True
        if dropped and self.blobs.is_dir():
            live = self._live()
            for p in self.blobs.glob("*.toml"):
                if p.stem not in live:
                    try:
                        p.unlink()
                    except OSError:
                        pass
                    self.sizes.pop(p.stem, None)

    def _live(self) -> set:
        live = {s[k] for s in self.steps for k in ("before", "after")}
        return live | {v for v in (self.head, self.opened) if v}

    # -------------------------------------------------------------- recording
    def sync(self, data: bytes, label: str = "changed outside the studio") -> bool:
        """Record the file's bytes ``data`` as a step if they are not the version last seen. True if recorded."""
        with self.lock:
            v = version_of(data)
            if self.head is None or self.blob(self.head) is None:
                self.seen = {v: data}          # kept in memory: nothing is written before the first change
                self.head = v
                self.opened = self.opened or v
                return False
            if v == self.head:
                self.opened = self.opened or v
                return False
            self._push(self.head, self._store(data), label)
            self.opened = self.opened or v
            self._save()
            return True

    def record(self, before: bytes, after: bytes, label: str) -> None:
        """Record a change the studio made (``before`` must be what the history last saw; see :meth:`sync`)."""
        with self.lock:
            self.sync(before)
            if version_of(after) != self.head:
                self._push(self.head, self._store(after), label)
                self._save()

    def _push(self, before: str, after: str, label: str) -> None:
        for v in (before, self.opened):             # versions seen so far become stored ones
            if v in self.seen:
                self._store(self.seen[v])
        del self.steps[self.position:]              # a new change forgets what was undone
        self.steps.append({"label": str(label)[:120], "before": before, "after": after, "time": time.time()})
        self.position = len(self.steps)
        self.head = after

    # -------------------------------------------------------------- moving
    def undo(self) -> tuple[bytes, dict]:
        """The bytes to write to undo the last applied step, and the step (the history moves on)."""
        with self.lock:
            if self.position == 0:
                raise InputError("nothing to undo")
            step = self.steps[self.position - 1]
            data = self.blob(step["before"])
            if data is None:
                raise InputError("the version before this step is no longer stored")
            self.position -= 1
            self.head = step["before"]
            self._save()
            return data, step

    def redo(self) -> tuple[bytes, dict]:
        """The bytes to write to redo the next undone step, and the step."""
        with self.lock:
            if self.position >= len(self.steps):
                raise InputError("nothing to redo")
            step = self.steps[self.position]
            data = self.blob(step["after"])
            if data is None:
                raise InputError("the version after this step is no longer stored")
            self.position += 1
            self.head = step["after"]
            self._save()
            return data, step

    def listing(self) -> dict:
        """What the page shows: the steps (label, time), how many are applied, whether undo / redo can run."""
        with self.lock:
            return {"steps": [{"label": s["label"], "time": s.get("time")} for s in self.steps],
                    "position": self.position, "can_undo": self.position > 0,
                    "can_redo": self.position < len(self.steps), "opened": self.opened, "head": self.head}
