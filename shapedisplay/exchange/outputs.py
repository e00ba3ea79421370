"""A played stroke into every file the designer asked for: WAV, trace, plot, AHAP, drive CSV — all or none."""
from __future__ import annotations

from shapedisplay.atomic import atomic_path
from shapedisplay.render.sinks import plot_trace, write_trace, write_wav


def play_to_files(renderer, cursor, wav, sample_format: str = "float32", trace=None, plot=None,
                  table_checksum: str = "", ahap=None, drive_csv=None, ahap_envelope: bool = True,
                  description: str = ""):
    """Render ``cursor`` with ``renderer`` and write the WAV, and the trace, plot, AHAP and drive CSV when asked:
    all or none.

    Every output goes to a temporary file beside its final name (opened before
    the render, so an unwritable place fails first) and is renamed only once
    all of them are written; an error leaves no output behind. The AHAP and
    drive CSV are described in :mod:`shapedisplay.exchange.ahap`
    (``ahap_envelope=False``: transients only; ``description`` goes to its
    metadata).

    Returns the :class:`~shapedisplay.render.renderer.RenderResult`.
    """
    from contextlib import ExitStack

    with ExitStack() as outputs:
        wav_tmp = outputs.enter_context(atomic_path(wav))
        trace_tmp = outputs.enter_context(atomic_path(trace, suffix=".npz")) if trace else None
        plot_tmp = outputs.enter_context(atomic_path(plot)) if plot else None
        ahap_tmp = outputs.enter_context(atomic_path(ahap)) if ahap else None
        csv_tmp = outputs.enter_context(atomic_path(drive_csv)) if drive_csv else None
        if plot_tmp is not None:      # read before the render: a bad widget map fails first
            from shapedisplay.table.widgets import widget_map
            widgets = widget_map(renderer.table)
        res = renderer.render(cursor)
        write_wav(wav_tmp, res.audio, res.audio_rate, sample_format)
        if trace_tmp is not None:
            write_trace(trace_tmp, res, table_checksum)
        if plot_tmp is not None:
            plot_trace(plot_tmp, res, widgets=widgets)
        if ahap_tmp is not None:
            from shapedisplay.exchange.ahap import ahap_of_result, write_ahap
            write_ahap(ahap_tmp, ahap_of_result(res, renderer.device.burst.carrier_hz, ahap_envelope, description))
        if csv_tmp is not None:
            from shapedisplay.exchange.ahap import write_drive_csv
            write_drive_csv(csv_tmp, res.audio, res.audio_rate)
    return res
