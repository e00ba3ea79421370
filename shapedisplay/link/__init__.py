"""Device link: wire protocol, host side, and a pty device emulator.

* :mod:`.framing` — COBS + CRC-32 frames and the incremental decoder;
* :mod:`.protocol` — message types and bodies (protocol version 1,
  ``docs/protocol.md``);
* :mod:`.host` — :class:`~.host.DeviceLink`, the host end (needs pyserial,
  the ``serial`` extra);
* :mod:`.emulator` — :class:`~.emulator.DeviceEmulator`, firmware behaviour
  on a pseudo-terminal, rendering with :mod:`shapedisplay.runtime`;
* :mod:`.c_engine` — the emulator's optional engine running the C99
  runtime of ``runtime-c/`` through ctypes.

Nothing here opens a port or imports pyserial at import time.
"""
