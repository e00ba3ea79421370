"""Height-map pictures and arrays: read and written through Pillow and numpy.

Functions for turning a picture file into one channel of numbers of shape
(rows, cols), *picture order* (row 0 is the top edge of the picture as it
is shown), and back. :mod:`shapedisplay.author.sources` turns these values into
heights and puts them on the height-field grid (row index growing with y,
see :func:`shapedisplay.author.heightfield.grid_from_picture`).

What is read
------------
Every format Pillow reads: PNG (1/2/4/8/16-bit grey, grey+alpha, RGB, RGBA,
palette with or without transparency, interlaced or not), JPEG, TIFF
(8/16-bit, 32-bit integer, 32-bit float), BMP, GIF, WebP. ``.npy`` arrays of
shape (rows, cols) or (cols,) are read with numpy. SVG pictures (icons) are
drawn to 8-bit RGBA pixels first (:mod:`shapedisplay.author.vector`) and read
as that PNG.

* **Integer pictures** keep their codes: ``full_scale`` is 255 for 8-bit
  channels and 65535 for 16-bit ones (1/2/4-bit grey is widened to 8 bits by
  Pillow: 0 and 255 stay the ends).
* **Float pictures** (32-bit float TIFF) are data in a physical unit, not
  gray values: ``full_scale`` is None.
* **Colour** is reduced to one channel chosen by ``channel``:
  ``luminance`` (default) is the ITU-R BT.709 luma of the stored (gamma
  encoded) values, ``Y' = 0.2126 R' + 0.7152 G' + 0.0722 B'``, the weights of
  HD video and sRGB; ``r``, ``g``, ``b``, ``a`` pick one channel. A palette
  picture is expanded through its palette first.
* **Alpha** (grey+alpha, RGBA, palette transparency) becomes a mask: samples
  with alpha 0 are outside the shape. ``channel="a"`` uses alpha as heights
  instead (no mask). A picture whose visible pixels all have one colour
  (within 1 % of full scale) while alpha varies -- the usual icon export,
  black or white on a transparent background -- has its shape only in
  alpha: with no channel named, alpha is read as heights (opaque = high),
  and the notes say so.
* **Normal maps**: a colour picture whose pixels decode as vectors
  ``n = 2 c / full_scale - 1`` pointing out of the surface (blue dominant,
  clustered around (128, 128, 255), near unit length: the blue-violet look
  of a tangent-space normal map, also after JPEG compression or hand
  painting, see :func:`normal_map_verdict`) is recognised;
  ``channel="normal"`` returns its slopes for integration, any other reading
  of such a picture is refused with that advice unless a channel is named.
  A picture that only may be one (a steep or painted map, a blue sky) is
  read as luminance with a :class:`PictureWarning` naming both channels.

Limits
------
The picture size is read from the file header (Pillow opens lazily) and
checked against :data:`shapedisplay.author.heightfield.MAX_SAMPLES` and
:data:`~shapedisplay.author.heightfield.MAX_SIDE` (samples a side) *before* any
pixel data is decoded, so an oversized or hostile file (a decompression
bomb, a picture of 1 x 100,000,000 pixels) is refused without exhausting
memory.

Pillow reads 16-bit-per-channel RGB/RGBA PNG at 8 bits per channel; such a
file is read that way with a warning that says so (convert it to 16-bit grey
to keep the depth).

Written pictures are 16-bit grey PNG through Pillow, with ``tEXt`` chunks
recording the height range and spacing.
"""
from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from shapedisplay.atomic import atomic_path
from shapedisplay.errors import FileFormatError, InputError, unknown_key
from shapedisplay.author.heightfield import check_grid_size

#: Suffixes read as pictures through Pillow (.svg drawn first by resvg, see :mod:`shapedisplay.author.vector`).
PICTURE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".gif", ".webp", ".svg")
#: Channel choices; "normal" integrates a tangent-space normal map.
CHANNELS = ("luminance", "r", "g", "b", "a", "normal")
#: ITU-R BT.709 luma weights of R', G', B'.
BT709 = (0.2126, 0.7152, 0.0722)
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Largest normal map integrated (``channel="normal"``): the Frankot-Chellappa integration holds about
#: :data:`FC_BYTES_PER_SAMPLE` bytes a pixel at its peak (a 4096 x 4096 map: about 2 GiB).
MAX_NORMAL_MAP_SAMPLES = 4096 * 4096
FC_BYTES_PER_SAMPLE = 128
#: How a picture beyond the size limits gets within them (one sample per pixel: no option resamples it).
PICTURE_FIX = "crop or resample the picture"


class PictureWarning(UserWarning):
    """A picture was read with a loss the user should know about (bit depth, frames)."""


@dataclass(frozen=True)
class Picture:
    """One channel of a picture file, in picture order (row 0 = top edge).

    Attributes
    ----------
    values : ndarray of shape (rows, cols)
        uint8/uint16 codes of an integer picture, float64 for luminance of a
        colour picture (still on the 0..full_scale scale), float32/float64
        for float data.
    full_scale : float or None
        Code of full scale (255, 65535) for integer pictures; None for float
        data (values in a physical unit).
    mask : ndarray of shape (rows, cols), bool, or None
        True where the picture is opaque (alpha > 0); None without alpha.
    slopes : tuple of two ndarrays or None
        ``channel="normal"``: (dh/dx, dh/dy) per pixel, picture order, x to the
        right and y *up* the picture.
    description : str
        Mode, bit depth and channel, for reports ("RGBA 8-bit, luminance BT.709").
    notes : list of str
        What was dropped or converted (alpha used as mask, frames ignored...).
    """

    values: np.ndarray
    full_scale: float | None
    mask: np.ndarray | None = None
    slopes: tuple | None = None
    description: str = ""
    notes: list = field(default_factory=list)


# ----------------------------------------------------------------- reading
def _open(path: Path, pixels=None):
    from PIL import Image
    if not path.exists():
        raise FileFormatError(f"image '{path}': no such file")
    if path.is_dir():
        raise FileFormatError(f"image '{path}': is a directory, not a file")
    if path.suffix.lower() == ".svg":          # drawn to RGBA pixels first, then read as the PNG it gives
        from shapedisplay.author.vector import rasterise_svg
        return rasterise_svg(path, pixels=pixels)
    try:
        with warnings.catch_warnings():
            # Pillow warns above its quiet limit; the caller checks the size against ours next
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            return Image.open(path)
    except PermissionError as exc:
        raise FileFormatError(f"image '{path}': unreadable ({exc.strerror or exc})") from None
    except Image.DecompressionBombError as exc:   # Pillow's own header check (its limit is below ours)
        raise InputError(f"image '{path}': refused before decoding: {exc}") from None
    except Exception as exc:  # UnidentifiedImageError, SyntaxError (broken header), OSError
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FileFormatError(f"image '{path}': not a picture Pillow can read ({msg}); readable: "
                              f"{', '.join(PICTURE_SUFFIXES)} or .npy") from None


def picture_info(path: str | os.PathLike) -> dict:
    """Size, mode and bit depth from the file header alone.

    Returns ``{"cols", "rows", "mode", "bit_depth", "format"}``; raises
    :class:`InputError` for a picture larger than the sample limit (nothing
    decoded yet).
    """
    path = Path(path)
    with _open(path) as im:
        cols, rows = im.size
        if cols == 0 or rows == 0:
            raise FileFormatError(f"image '{path}': empty image ({cols}x{rows} pixels)")
        check_grid_size(rows, cols, f"image '{path}'", PICTURE_FIX)
        return {"cols": cols, "rows": rows, "mode": im.mode, "bit_depth": _bit_depth(im, path),
                "format": im.format}


def _bit_depth(im, path: Path) -> int:
    """Bits per channel as stored in the file (PNG header read directly for 16-bit colour)."""
    if im.format == "PNG":
        with open(path, "rb") as fh:
            head = fh.read(33)
        if len(head) == 33 and head.startswith(PNG_SIGNATURE):
            return head[24]
    if im.mode in ("I;16", "I;16B", "I;16L", "I;16N"):
        return 16
    if im.mode in ("I", "F"):
        return 32
    return 8


def read_picture(path: str | os.PathLike, channel: str | None = None, *, pixels=None) -> Picture:
    """Read one channel of a picture (see the module docstring).

    Parameters
    ----------
    path : path-like
        Any picture Pillow reads (PNG, JPEG, TIFF, ...).
    channel : {"luminance", "r", "g", "b", "a", "normal"} or None
        Which channel of a colour picture; None = luminance, refusing a
        picture that looks like a normal map. Grey pictures take None,
        "luminance" (the grey value) or "a" (their alpha).
    pixels : (cols, rows) or None
        An SVG's least raster (:func:`shapedisplay.author.vector.rasterise_svg`);
        pixel pictures keep their own pixels.

    Returns
    -------
    Picture

    Raises
    ------
    FileFormatError
        Missing, unreadable, truncated or corrupt file; a channel the picture
        does not have.
    InputError
        The header announces a picture too large to hold in memory; a normal
        map read without ``channel``.
    """
    path = Path(path)
    if channel is not None and channel not in CHANNELS:
        raise unknown_key("image channel", channel, CHANNELS)
    with _open(path, pixels) as im:
        cols, rows = im.size
        if cols == 0 or rows == 0:
            raise FileFormatError(f"image '{path}': empty image ({cols}x{rows} pixels)")
        check_grid_size(rows, cols, f"image '{path}'", PICTURE_FIX)     # before any pixel is decoded
        depth = _bit_depth(im, path)
        notes = []
        if getattr(im, "n_frames", 1) > 1:
            notes.append(f"first of {im.n_frames} frames used")
        from PIL import Image
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", Image.DecompressionBombWarning)   # our limit was checked
                im.load()
        except Exception as exc:   # truncated data, bad CRC, decoder errors
            msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise FileFormatError(f"image '{path}': corrupt or truncated pixel data ({msg})") from None
        return _channel(im, path, channel, depth, notes)


def _channel(im, path: Path, channel: str | None, depth: int, notes: list) -> Picture:
    mode = im.mode
    where = f"image '{path}'"
    if mode == "P":
        im = im.convert("RGBA" if "transparency" in im.info else "RGB")
        notes.append("palette expanded")
        mode = im.mode
    elif mode == "PA":
        im, mode = im.convert("RGBA"), "RGBA"
        notes.append("palette expanded")
    elif mode in ("CMYK", "YCbCr", "LAB", "HSV", "RGBX", "RGBa"):
        im, mode = im.convert("RGB"), "RGB"
    elif mode == "La":
        im, mode = im.convert("LA"), "LA"
    elif mode == "1":
        im, mode = im.convert("L"), "L"
    elif mode == "I;16B" or mode == "I;16L" or mode == "I;16N":
        im, mode = im.convert("I;16"), "I;16"
    grey = mode in ("L", "LA", "I;16", "I", "F")
    has_alpha = mode in ("LA", "RGBA")
    colour = mode in ("RGB", "RGBA")
    if not (grey or colour):
        raise FileFormatError(f"{where}: picture mode {mode} is not supported; save it as grey or RGB(A)")
    if colour and depth == 16:
        warnings.warn(f"{where}: 16-bit-per-channel colour is read at 8 bits per channel (Pillow's limit); "
                      f"save the height map as 16-bit grey to keep its depth", PictureWarning, stacklevel=3)
        notes.append("16-bit colour read at 8 bits per channel")
    arr = np.asarray(im)
    if mode == "I":
        # 32-bit integer TIFF, or 16-bit data Pillow widened
        full = 65535.0 if depth <= 16 else float(2 ** 32 - 1)
        vmin = int(arr.min()) if arr.size else 0
        if vmin < 0:
            raise FileFormatError(f"{where}: signed 32-bit integer pixels (min {vmin}) are not supported; "
                                  f"save the heights as 32-bit float TIFF or .npy")
        arr = arr.astype(np.uint16) if full == 65535.0 else arr.astype(np.float64)
    elif mode == "F":
        return Picture(np.array(arr, dtype=np.float32), None, None, None, "32-bit float", notes)
    else:
        full = 65535.0 if mode == "I;16" else 255.0

    if channel == "normal":
        if not colour:
            raise FileFormatError(f"{where}: `channel` 'normal' needs an RGB normal map (got a {mode} picture)")
        if arr.shape[0] * arr.shape[1] > MAX_NORMAL_MAP_SAMPLES:
            raise InputError(f"{where}: a normal map of {arr.shape[1]} x {arr.shape[0]} pixels; integrating one takes "
                             f"about {FC_BYTES_PER_SAMPLE} bytes a pixel, so at most {MAX_NORMAL_MAP_SAMPLES} pixels "
                             f"(4096 x 4096) are integrated (shapedisplay.author.imageio.MAX_NORMAL_MAP_SAMPLES): "
                             f"resample the map")
        slopes = _normal_slopes(arr[..., :3], full, where, strict=True)
        return Picture(np.zeros(arr.shape[:2]), full, _mask(arr, has_alpha), slopes,
                       f"{mode} {depth}-bit tangent-space normal map (+y green)", notes)
    if channel == "a":
        if not has_alpha:
            raise FileFormatError(f"{where}: has no alpha channel (mode {mode}); choose luminance, r, g or b")
        return Picture(np.ascontiguousarray(arr[..., -1]), full, None, None, f"{mode} {depth}-bit, alpha", notes)
    if grey:
        if channel in ("r", "g", "b"):
            raise FileFormatError(f"{where}: is a grey picture (mode {mode}); `channel` '{channel}' needs colour "
                                  f"(use luminance or omit it)")
        values = np.ascontiguousarray(arr[..., 0] if has_alpha else arr)
        desc = f"grey {depth}-bit" + (" + alpha (mask)" if has_alpha else "")
    else:
        rgb = arr[..., :3]
        one_colour = channel is None and has_alpha and _shape_in_alpha(
            rgb[..., 0] * BT709[0] + rgb[..., 1] * BT709[1] + rgb[..., 2] * BT709[2], arr[..., -1], full)
        verdict = normal_map_verdict(rgb, full) if channel is None and not one_colour else (None, {})
        if verdict[0] == "normal":
            raise InputError(
                f"{where}: looks like a tangent-space normal map (pixels are vectors pointing out of the "
                f"surface); pass `--channel normal` to integrate it into heights (Frankot-Chellappa), or name "
                f"another channel (luminance, r, g, b) to use its values as heights")
        if verdict[0] == "maybe":
            st = verdict[1]
            blue = max(st['facing'], st['blue']) * 100
            warnings.warn(f"{where}: may be a tangent-space normal map ({blue:.0f} % of the pixels blue dominant, "
                          f"median vector length {st['median_length']:.2f}); read as luminance heights: pass `--channel normal` to integrate it as a normal map, or `--channel "
                          f"luminance` to keep this reading without the warning", PictureWarning, stacklevel=3)
            notes.append("may be a normal map: read as luminance (pass a channel to decide)")
        if one_colour:
            notes.append("uniform colour: the shape is in the alpha channel, read as heights (opaque = high)")
            return Picture(np.ascontiguousarray(arr[..., -1]), full, None, None,
                           f"{mode} {depth}-bit, alpha (uniform colour)", notes)
        if channel in ("r", "g", "b"):
            values = np.ascontiguousarray(rgb[..., "rgb".index(channel)])
            desc = f"{mode} {depth}-bit, channel {channel}"
        else:
            w = BT709
            values = rgb[..., 0] * w[0] + rgb[..., 1] * w[1] + rgb[..., 2] * w[2]   # float64
            desc = f"{mode} {depth}-bit, luminance (ITU-R BT.709)"
        if has_alpha:
            desc += " + alpha (mask)"
    if grey and channel is None and has_alpha and _shape_in_alpha(values, arr[..., -1], full):
        notes.append("uniform colour: the shape is in the alpha channel, read as heights (opaque = high)")
        return Picture(np.ascontiguousarray(arr[..., -1]), full, None, None,
                       f"{mode} {depth}-bit, alpha (uniform colour)", notes)
    mask = _mask(arr, has_alpha)
    if mask is not None:
        notes.append(f"alpha used as mask: {int((~mask).sum())} transparent pixels are outside the shape")
    return Picture(values, full, mask, None, desc, notes)


def _shape_in_alpha(values: np.ndarray, alpha: np.ndarray, full: float) -> bool:
    """True for an icon exported as one colour on a transparent background: the colour of every pixel at
    least a quarter opaque is the same (within 1 % of full scale) while alpha varies, so the shape is only
    in alpha. (Nearly transparent edge pixels are left out: renderers store their colour only roughly.)"""
    seen = alpha >= 0.25 * full
    if not seen.any() or alpha.min() == alpha.max():
        return False
    v = values[seen]
    return float(v.max()) - float(v.min()) <= 0.01 * full and int(alpha.max()) - int(alpha.min()) > 0.1 * full


def _mask(arr: np.ndarray, has_alpha: bool):
    if not has_alpha:
        return None
    m = arr[..., -1] > 0
    return None if m.all() else m


def _normal_vectors(rgb: np.ndarray, full: float) -> np.ndarray:
    return rgb.astype(np.float64) * (2.0 / full) - 1.0


def normal_map_stats(rgb: np.ndarray, full: float) -> dict:
    """The statistics that tell a tangent-space normal map from a picture of heights.

    With ``n = 2 c / full_scale - 1`` over a sample of at most ~64k pixels:
    ``unit`` the fraction of exactly unit vectors (``| |n| - 1 | < 0.1``,
    ``nz > 0``: what a map written straight from computed normals holds);
    ``near_unit`` the fraction with ``0.5 < |n| < 1.25`` (real maps: JPEG,
    resampling and hand painting leave their vectors short, median length about
    0.8, 5-95 % 0.6-1.07); ``facing`` the fraction that is blue dominant and
    faces out of the surface (``nz > 0.3`` and, after normalisation, ``nz``
    larger than ``|nx|`` and ``|ny|``: slopes under 45 degrees); ``outward``
    the fraction with ``nz > 0.1`` (steeper slopes too); ``blue`` the
    fraction whose stored blue exceeds red and green by a tenth of full
    scale (the look of any normal map, also one stored darkened or in
    another range, such as three.js's water normals at mean (85, 85, 167));
    ``tilt`` the
    larger of the medians of the normalised ``|nx|``, ``|ny|`` components (the
    colour cluster sits at (128, 128, 255) for a map of a surface that is
    mostly flat); ``mean_nz`` and ``median_length``.
    """
    step = max(1, int(np.sqrt(rgb.shape[0] * rgb.shape[1] / 65536)))   # a sample of at most ~64k pixels
    n = _normal_vectors(rgb[::step, ::step], full).reshape(-1, 3)
    length = np.sqrt((n * n).sum(axis=-1))
    u = n / np.maximum(length, 1e-9)[:, None]
    facing = (n[:, 2] > 0.3) & (u[:, 2] > np.maximum(np.abs(u[:, 0]), np.abs(u[:, 1])))
    c = rgb[::step, ::step].reshape(-1, 3).astype(np.float64)
    blue = c[:, 2] - np.maximum(c[:, 0], c[:, 1]) >= 0.1 * full
    return {"blue": float(blue.mean()),"unit": float(((np.abs(length - 1.0) < 0.1) & (n[:, 2] > 0)).mean()),
            "near_unit": float(((length > 0.5) & (length < 1.25)).mean()),
            "facing": float(facing.mean()), "outward": float((n[:, 2] > 0.1).mean()),
            "tilt": float(max(abs(np.median(u[:, 0])), abs(np.median(u[:, 1])))),
            "mean_nz": float(n[:, 2].mean()), "median_length": float(np.median(length))}


def normal_map_verdict(rgb: np.ndarray, full: float) -> tuple[str | None, dict]:
    """``("normal", stats)``, ``("maybe", stats)`` or ``(None, stats)`` for a colour picture.

    "normal": at least 95 % exactly unit vectors with mean ``nz`` above 0.5
    (a map written from computed normals), or at least 90 % near unit, 90 %
    facing and a tilt under 0.35 (a real map: compressed, resampled or
    painted). "maybe": at least 60 % near unit and either 60 % facing or
    90 % outward with mean ``nz`` above 0.4 (a map with steep or painted
    areas), or 90 % blue (a map stored in another range, or a blue picture
    such as a sky). Photographs,
    screenshots and grey pictures fail the facing test: grey is never blue
    dominant. See :func:`normal_map_stats`.
    """
    st = normal_map_stats(rgb, full)
    if st["unit"] >= 0.95 and st["mean_nz"] > 0.5 or \
            st["near_unit"] >= 0.9 and st["facing"] >= 0.9 and st["tilt"] < 0.35:
        return "normal", st
    if st["near_unit"] >= 0.6 and (st["facing"] >= 0.6 or st["outward"] >= 0.9 and st["mean_nz"] > 0.4) or \
            st["blue"] >= 0.9:
        return "maybe", st
    return None, st


def looks_like_normal_map(rgb: np.ndarray, full: float) -> bool:
    """True if the picture is a tangent-space normal map (:func:`normal_map_verdict` says "normal")."""
    return normal_map_verdict(rgb, full)[0] == "normal"


def _normal_slopes(rgb: np.ndarray, full: float, where: str, strict: bool):
    n = _normal_vectors(rgb, full)
    nz = n[..., 2]
    bad = nz <= 0.05
    if strict and bad.mean() > 0.05:
        raise InputError(f"{where}: is not a tangent-space normal map: {bad.mean() * 100:.3g} % of the pixels point "
                         f"sideways or into the surface (blue below 0.525 of full scale)")
    nz = np.maximum(nz, 0.05)       # a slope of at most ~20 per pixel: a wall, bounded
    # picture order: +x to the right, green = +y up the picture (OpenGL convention)
    return (-n[..., 0] / nz, -n[..., 1] / nz)


def frankot_chellappa(p: np.ndarray, q: np.ndarray, dx: float = 1.0, dy: float = 1.0) -> np.ndarray:
    """Integrate a gradient field into heights (Frankot and Chellappa 1988).

    The least-squares integrable surface in the Fourier domain:
    ``Z = F^-1[ -i (wx P + wy Q) / (wx^2 + wy^2) ]`` with the mean height 0.
    The field is mirrored to four times its size first, which makes it
    periodic without the seam artefacts a plain FFT puts at the borders.

    Parameters
    ----------
    p, q : ndarray of shape (rows, cols), float
        dh/dx (along columns) and dh/dy (along rows, row index growing with y).
    dx, dy : float
        Sample spacing along x and y (any length unit; heights come out in it).

    Returns
    -------
    ndarray of shape (rows, cols), float64
        Heights with zero mean.
    """
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    rows, cols = p.shape
    # even extension: p is odd in x and even in y, q the other way round; real transforms (half the
    # spectrum) and in-place products keep the peak near 100 bytes a pixel of the field
    P = np.block([[p, -p[:, ::-1]], [p[::-1, :], -p[::-1, ::-1]]])
    Z = np.fft.rfft2(P)
    del P
    wx = 2 * np.pi * np.fft.rfftfreq(2 * cols, d=dx)[None, :]
    wy = 2 * np.pi * np.fft.fftfreq(2 * rows, d=dy)[:, None]
    Z *= wx
    Q = np.block([[q, q[:, ::-1]], [-q[::-1, :], -q[::-1, ::-1]]])
    Qf = np.fft.rfft2(Q)
    del Q
    Qf *= wy
    Z += Qf
    del Qf
    Z *= -1j
    for r in range(0, Z.shape[0], 256):                   # / (wx^2 + wy^2), a band of rows at a time
        Z[r:r + 256] /= np.maximum(wx ** 2 + wy[r:r + 256] ** 2, np.finfo(np.float64).tiny)
    Z[0, 0] = 0.0
    Z[:, -1] = 0.0                  # the Nyquist frequencies: a slope there has no sign to integrate
    Z[rows] = 0.0
    z = np.fft.irfft2(Z, s=(2 * rows, 2 * cols))[:rows, :cols]
    return z - z.mean()


# ----------------------------------------------------------------- writing
def encode_png(gray: np.ndarray, text: dict | None = None) -> bytes:
    """Encode a grey picture as PNG bytes (picture order: row 0 is the top edge).

    Parameters
    ----------
    gray : ndarray of shape (rows, cols), uint8 or uint16
        Gray values (bit depth follows the dtype).
    text : dict, optional
        ``{keyword: value}`` written as PNG ``tEXt`` chunks (Latin-1).
    """
    import io

    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    gray = np.asarray(gray)
    if gray.ndim != 2 or gray.size == 0:
        raise InputError(f"`gray` must be a non-empty 2-D array (got shape {gray.shape})")
    if gray.dtype == np.uint8:
        im = Image.fromarray(np.ascontiguousarray(gray))          # mode L
    elif gray.dtype == np.uint16:
        im = Image.frombytes("I;16", (gray.shape[1], gray.shape[0]), gray.astype("<u2").tobytes())
    else:
        raise InputError(f"`gray` must be uint8 or uint16 (got {gray.dtype})")
    info = PngInfo()
    for k, v in (text or {}).items():
        info.add_text(str(k), str(v))
    buf = io.BytesIO()
    im.save(buf, format="PNG", pnginfo=info, compress_level=6)
    return buf.getvalue()


def write_png(path: str | os.PathLike, gray: np.ndarray, text: dict | None = None) -> Path:
    """Write a grey PNG atomically (see :func:`encode_png`). Returns the path."""
    data = encode_png(gray, text)
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return path


def png_text(path: str | os.PathLike) -> dict:
    """The ``tEXt`` chunks of a PNG as a dict (what :func:`write_png` recorded)."""
    with _open(Path(path)) as im:
        return dict(getattr(im, "text", {}) or {})


# ----------------------------------------------------------------- npy
def read_npy(path: str | os.PathLike) -> np.ndarray:
    """Read a ``.npy`` height array of shape (rows, cols) or (cols,).

    The shape is checked from the file header before the data is read.
    Returns the stored array (integer or float dtype; bool and complex are
    refused).
    """
    path = Path(path)
    try:
        fh = open(path, "rb")
    except FileNotFoundError:
        raise FileFormatError(f"array '{path}': no such file") from None
    except OSError as exc:
        raise FileFormatError(f"array '{path}': unreadable ({exc.strerror or exc})") from None
    with fh:
        try:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            else:
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
        except (ValueError, OSError, SyntaxError) as exc:
            raise FileFormatError(f"array '{path}': not a .npy file ({exc})") from None
        if len(shape) not in (1, 2):
            raise FileFormatError(f"array '{path}': heights must have shape (rows, cols) or (cols,) (got {shape})")
        if dtype.kind not in "uif":
            raise FileFormatError(f"array '{path}': dtype {dtype} is not supported; use an integer or float array")
        rows, cols = (1, shape[0]) if len(shape) == 1 else shape
        check_grid_size(rows, cols, f"array '{path}'", "crop or resample the array")
        fh.seek(0)
        try:
            arr = np.load(fh, allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise FileFormatError(f"array '{path}': truncated or corrupt ({exc})") from None
    return arr


__all__ = ["PICTURE_SUFFIXES", "CHANNELS", "BT709", "Picture", "PictureWarning", "picture_info", "read_picture",
           "normal_map_stats", "normal_map_verdict",
           "looks_like_normal_map", "frankot_chellappa", "encode_png", "write_png", "png_text", "read_npy"]
