"""The studio: design a tactile screen in a browser and feel it while you edit.

``shapedisplay studio SOURCE`` serves a local web app (Starlette + Uvicorn) on
127.0.0.1: a top view of the compiled table, the compile report, a scene
editor, live feel through the C runtime compiled to WebAssembly and run in an
AudioWorklet, record/replay of strokes, and exports. Saving the scene (in the
page or in any editor) recompiles and swaps the table into the running
worklet. Needs the ``studio`` extra: ``pip install 'shapedisplay[studio]'``.

Modules: :mod:`.session` (source, compile, last good table), :mod:`.lines`
(scene errors -> line numbers), :mod:`.wasm` (the WebAssembly build and table
layout), :mod:`.views` (top view, 3D snapshot), :mod:`.exports`, :mod:`.app`
(routes, security gate, watcher), :mod:`.server` (sockets, URL, start/stop).
"""
