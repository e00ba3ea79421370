"""The scene file as the studio edits it: versions, edits, undo / redo and conflicts.

The file on disk is the truth. Every change the page makes names the version
(:func:`~shapedisplay.studio.edits.version_of` of the bytes) it was made
on; if the file changed on disk since (another editor, another page), the
change is not written: :class:`Conflict` carries the disk's text and what the
page's change would have made of its own version, and the designer chooses
(:meth:`SceneFile.resolve`: keep the page's, take the disk's, or merge the
changes that do not touch the same lines). Every write is atomic, recorded in
the :class:`~shapedisplay.studio.history.History`, and TOML that parses:
a text the page saves that is not TOML is refused with the parser's message
(its line), and undo / redo step over any version that does not parse.
"""
from __future__ import annotations

import threading
from pathlib import Path

from shapedisplay.errors import InputError
from shapedisplay.studio import edits
from shapedisplay.studio.edits import version_of
from shapedisplay.studio.history import History
from shapedisplay.studio.session import MAX_SCENE_BYTES


class Conflict(InputError):
    """The file changed on disk since the version the page edited; nothing was written."""

    def __init__(self, message: str, disk: bytes, base: str | None, mine: str | None):
        super().__init__(message)
        self.disk, self.base, self.mine = disk, base, mine

    def payload(self) -> dict:
        return {"conflict": str(self), "disk": self.disk.decode("utf-8", "replace"),
                "disk_version": version_of(self.disk), "base": self.base, "mine": self.mine}


def _parses(data: bytes) -> bool:
    try:
        edits.check_toml(data.decode("utf-8"), "")
        return True
    except (InputError, UnicodeDecodeError):
        return False


class SceneFile:
    """Edits of one scene file, each checked against the version the page edited."""

    def __init__(self, path: Path, out_dir: Path, device=None):
        self.path = Path(path)
        self.device = device                  # a callable giving the --device profile, or None
        self.history = History(Path(out_dir) / f"history-{self.path.stem}")
        self.lock = threading.Lock()

    def read(self) -> bytes:
        return self.path.read_bytes()

    def version(self) -> str:
        return version_of(self.read())

    def text(self) -> str:
        return self.read().decode("utf-8")

    def sync(self) -> bool:
        """Record a change made outside the studio as a step (see History.sync)."""
        try:
            return self.history.sync(self.read())
        except OSError:
            return False
        finally:
            self.history.flush()

    def _device(self):
        return self.device() if callable(self.device) else self.device

    def _current(self, base, what: str, mine=None) -> bytes:
        """The file's bytes, checked to be the version ``base`` the page edited (else :class:`Conflict`)."""
        data = self.read()
        self.history.sync(data)
        if not isinstance(base, str) or not base:
            raise InputError(f"{what}: say which version of the file you edited (`base`)")
        if version_of(data) != base:
            m = mine() if callable(mine) else mine
            raise Conflict(f"{what}: the file changed on disk since this page read it; nothing was written",
                           data, base, m)
        return data

    def _write(self, before: bytes, text: str, label: str) -> str:
        data = text.encode("utf-8")
        if len(data) > MAX_SCENE_BYTES:
            raise InputError(f"scene text must be at most {MAX_SCENE_BYTES} bytes (got {len(data)})")
        self._replace(data)
        self.history.record(before, data, label)
        return version_of(data)

    def _replace(self, data: bytes) -> None:
        """Replace the file by ``data`` in one rename (never a partial file); :meth:`flush` puts it on
        disk once the new table is on its way, so that the disk's latency is not the designer's."""
        import os
        tmp = self.path.with_name(f".{self.path.name}.studio.part")
        with open(tmp, "wb") as f:
            f.write(data)
        try:
            os.chmod(tmp, self.path.stat().st_mode & 0o777)
        except OSError:
            pass
        os.replace(tmp, self.path)
        self.unflushed = True

    def flush(self) -> None:
        """Write the history's index and flush the last write of the file to disk (the file and its
        folder's entry)."""
        import os
        self.history.flush()
        if not getattr(self, "unflushed", False):
            return
        self.unflushed = False
        try:
            fd = os.open(self.path, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            fd = os.open(self.path.parent, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        except OSError:
            pass

    # -------------------------------------------------------------- changes
    def edit(self, base, ops: list, label: str) -> dict:
        """Apply the page's operations (:func:`edits.apply_ops`) to the version ``base``; validated, recorded."""
        with self.lock:
            def mine():
                old = self.history.blob(base)
                try:
                    return edits.apply_ops(old.decode("utf-8"), ops, self.path, self._device())[0] if old else None
                except (InputError, UnicodeDecodeError):
                    return None
            data = self._current(base, label, mine)
            text, select = edits.apply_ops(data.decode("utf-8"), ops, self.path, self._device())
            if text == data.decode("utf-8"):
                return {"version": version_of(data), "select": select, "changed": False}
            return {"version": self._write(data, text, label), "select": select, "changed": True}

    def save_text(self, base, text: str) -> dict:
        """Save the page's editor text over the version ``base``: TOML only, recorded."""
        if len(text.encode("utf-8")) > MAX_SCENE_BYTES:
            raise InputError(f"scene text must be at most {MAX_SCENE_BYTES} bytes")
        edits.check_toml(text, self.path)
        with self.lock:
            data = self._current(base, "text edit", text)
            if text == data.decode("utf-8"):
                return {"version": version_of(data), "changed": False}
            return {"version": self._write(data, text, "text edit"), "changed": True}

    def _move(self, base, step) -> dict:
        with self.lock:
            self._current(base, "undo" if step == "undo" else "redo")
            move = self.history.undo if step == "undo" else self.history.redo
            labels = []
            while True:
                data, s = move()
                labels.append(s["label"])
                if _parses(data):
                    break
                if not (self.history.listing()["can_undo" if step == "undo" else "can_redo"]):
                    raise InputError(f"nothing to {step}: the only versions left do not parse as TOML")
            self._replace(data)
            return {"version": version_of(data), "label": labels[0], "changed": True}

    def undo(self, base) -> dict:
        """Write back the bytes the file held before the last applied step."""
        return self._move(base, "undo")

    def redo(self, base) -> dict:
        """Write again the bytes of the next undone step."""
        return self._move(base, "redo")

    def revert(self, base) -> dict:
        """Write back the file as it was when the studio opened it (a step of its own, undoable)."""
        with self.lock:
            data = self._current(base, "revert")
            opened = self.history.blob(self.history.opened)
            if opened is None:
                raise InputError("the file as opened is no longer stored")
            if opened == data:
                return {"version": version_of(data), "changed": False}
            return {"version": self._write(data, opened.decode("utf-8"), "revert to the file as opened"),
                    "changed": True}

    def resolve(self, choice: str, base, mine, disk_version) -> dict:
        """The designer's answer to a :class:`Conflict`: ``mine``, ``disk`` or ``merge``."""
        if choice not in ("mine", "disk", "merge"):
            raise InputError(f"`choice` must be mine, disk or merge (got {choice!r})")
        with self.lock:
            data = self.read()
            self.history.sync(data)
            if choice == "disk":
                return {"version": version_of(data), "changed": False, "conflicts": []}
            if version_of(data) != disk_version:
                raise Conflict("the file changed on disk again; nothing was written", data, base, mine)
            if not isinstance(mine, str):
                raise InputError("`mine` must be the page's text")
            conflicts = []
            text = mine
            if choice == "merge":
                old = self.history.blob(base)
                if old is None:
                    raise InputError("the version this page edited is no longer stored: keep yours or take the disk's")
                text, conflicts = edits.merge3(old.decode("utf-8"), mine, data.decode("utf-8"))
            edits.check_toml(text, self.path)
            label = "kept the page's version" if choice == "mine" else "merged the page's changes"
            if text == data.decode("utf-8"):
                return {"version": version_of(data), "changed": False, "conflicts": conflicts}
            return {"version": self._write(data, text, label), "changed": True, "conflicts": conflicts}
