"""Device link: wire protocol, host side, and a pty device emulator.

* :mod:`.framing` — COBS + CRC-32 frames and the incremental decoder;
* :mod:`.protocol` — message types and bodies (protocol version 1,
  ``docs/protocol.md``);
* :mod:`.host` — :class:`~.host.DeviceLink`, the host end (needs pyserial,
  the ``serial`` extra);
* :mod:`.engine` — :class:`~.engine.RenderEngine`, the device's renderer
  (cursor samples in, one drive value per tick out), shared by the emulator,
  the host's actuator-stream mode and the C engine;
* :mod:`.emulator` — :class:`~.emulator.DeviceEmulator`, firmware behaviour
  on a pseudo-terminal (transport, upload, queue, fault injection), rendering
  through :mod:`.engine` (the C engine's ticks, through
  :class:`~shapedisplay.render.Renderer`);
* :mod:`.session` — :class:`~.session.DeviceSession` (and the shortcuts
  :func:`~.session.upload`, :func:`~.session.play`): upload a table and play
  a stroke from Python, recording what the device played; the library
  behind ``shapedisplay device upload|play``.

Nothing here opens a port or imports pyserial at import time.
"""
