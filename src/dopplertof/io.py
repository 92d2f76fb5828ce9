"""Image files, written atomically: EXR and NPY keep the signed values; PNG is a preview.

Every writer renders to a temporary file in the target folder and renames it into
place, so that a failed or interrupted write never leaves a partial file and never
replaces a good one.

Output folders, one rule for every command: a missing output folder (and its missing
parents) is created when the first file is written into it; before any work,
:func:`check_output_folder` refuses a path that cannot become one (a file in the way,
no write permission), so that bad input writes nothing, not even a folder.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile

import numpy as np

FORMATS = (".exr", ".npy", ".png")


class OutputError(ValueError):
    """An output path that cannot be written (unknown extension, missing folder...)."""


#: what every command's --help says about its output folder
FOLDER_HELP = "created, with missing parents, if missing"


def check_output_folder(folder) -> str:
    """Before any work: ``folder`` is an existing writable folder, or a missing one that
    can be created (its nearest existing ancestor is a writable folder). Creates
    nothing; the writers create it. Returns the absolute path."""
    folder = os.path.abspath(os.fspath(folder))
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise OutputError(f"output path exists and is not a folder: {folder}")
    existing = folder
    while not os.path.exists(existing):
        existing = os.path.dirname(existing)
    if not os.path.isdir(existing):
        raise OutputError(f"cannot create the output folder {folder}: {existing} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(f"output folder is not writable: {existing}")
    return folder


def make_output_folder(folder) -> str:
    """Check ``folder`` (:func:`check_output_folder`) and create it; returns its path."""
    folder = check_output_folder(folder)
    os.makedirs(folder, exist_ok=True)
    return folder


def check_output_path(path) -> str:
    """Validate an output file path before any work is done; returns its extension.
    A missing folder is created when the file is written."""
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in FORMATS:
        raise OutputError(f"unknown output extension {ext or '(none)'!r} in {path}: "
                          f"use one of {', '.join(FORMATS)}")
    if os.path.isdir(path):
        raise OutputError(f"output path is a folder: {path}")
    check_output_folder(os.path.dirname(os.path.abspath(path)))
    return ext


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path`` (same extension); rename on success.
    A missing folder is created first."""
    path = os.fspath(path)
    folder = make_output_folder(os.path.dirname(os.path.abspath(path)))
    base, ext = os.path.splitext(os.path.basename(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{base}.", suffix=f".tmp{ext}", dir=folder)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600: follow the umask instead
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_npy(path, array: np.ndarray) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.save(f, np.asarray(array))


def write_json(path, data: dict) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(data, f, indent=2, sort_keys=True, default=_json_default)
            f.write("\n")


def _json_default(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def write_exr(path, image: np.ndarray, metadata: dict | None = None) -> None:
    """Float32 OpenEXR via Mitsuba's Bitmap (needs a Mitsuba variant set)."""
    import mitsuba as mi

    img = np.ascontiguousarray(np.asarray(image, dtype=np.float32))
    if img.ndim == 2:
        img = img[..., None]
    bitmap = mi.Bitmap(img)
    if metadata:
        props = bitmap.metadata()
        for key, value in metadata.items():
            text = value if isinstance(value, str) else json.dumps(value, default=_json_default)
            props[f"dopplertof.{key}"] = text
    with atomic_path(path) as tmp:
        bitmap.write(tmp)


def measurement_title(kind: str, hetero_frequency: float, offset: float, w_g_mhz: float,
                      detail: str = "") -> str:
    """The title of a capture's preview: what was measured."""
    return (f"{kind} capture, offset {offset:.4g}, h={hetero_frequency:.4g}, "
            f"{w_g_mhz:.4g} MHz{detail}")


def render_title(metadata: dict) -> str:
    """The preview title of a render, from its metadata (h, offset, frequency, waveform)."""
    import math

    exposure = metadata["exposure_s"]
    h = metadata["omega_d_rad_s"] * exposure / (2 * math.pi)
    h = 0.0 if abs(h) < 1e-9 else h
    offset = (metadata["psi_rad"] / (2 * math.pi)) % 1.0
    kind = "homodyne" if h == 0 else "heterodyne"
    waveform = metadata.get("params", {}).get("wave_function_type", "")
    return measurement_title(kind, h, offset,
                             metadata["omega_g_rad_s"] / (2 * math.pi * 1e6),
                             f" {waveform}, {metadata['spp']} spp" if waveform else "")


def robust_limit(data: np.ndarray, percentile: float = 99.5) -> float:
    """A colour limit for |data| that thin features (silhouettes sweeping through pixels
    during the exposure, one or two pixels wide) do not set: the ``percentile`` of |data|
    after a 3x3 median filter, or of |data| itself when the filter leaves nothing."""
    from scipy.ndimage import median_filter

    values = np.abs(np.asarray(data, np.float64))
    finite = np.isfinite(values)
    if not finite.any():
        return 1.0
    smooth = median_filter(np.where(finite, values, 0.0), size=3, mode="nearest")
    for candidate in (smooth[finite], values[finite]):
        limit = float(np.percentile(candidate, percentile))
        if limit > 0:
            return limit
    return 1.0


#: "no signal" (NaN) in every preview: black hatching on a magenta that none of the colour
#: maps used (RdBu, PuOr, viridis, gray) contains, so that it cannot pass for a value
NO_SIGNAL_COLOUR = "#ff00ff"
NO_SIGNAL_NOTE = "hatched magenta: NaN (nothing hit or signal too weak)"


def no_signal_colours(cmap: str):
    """The colour map ``cmap`` with NaN transparent: the hatching behind shows through."""
    import matplotlib

    return matplotlib.colormaps[cmap].with_extremes(bad=(0.0, 0.0, 0.0, 0.0))


def show_no_signal(ax, shape) -> None:
    """Hatch the area of an image of ``shape`` (drawn on ``ax`` above zorder 0)."""
    from matplotlib.patches import Rectangle

    h, w = shape[:2]
    ax.add_patch(Rectangle((-0.5, -0.5), w, h, facecolor=NO_SIGNAL_COLOUR, edgecolor="black",
                           hatch="////", linewidth=0, zorder=0))


def preview_scalar(image: np.ndarray) -> np.ndarray:
    """The signed scalar a preview shows: the mean over channels."""
    img = np.asarray(image, dtype=np.float64)
    return img.mean(axis=-1) if img.ndim == 3 else img


def write_png(path, image: np.ndarray, title: str = "D-ToF measurement",
              label: str = "time-averaged correlation (mean of channels)",
              cmap: str = "RdBu_r", metadata: dict | None = None,
              signed: bool = True) -> None:
    """Signed preview: diverging colormap centred on zero, with a colour bar; with
    ``signed=False`` a colour scale from zero to the maximum (counts, magnitudes)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    data = preview_scalar(image)
    finite = data[np.isfinite(data)]
    if signed:  # robust: the colour bar's arrows show what saturates
        vmax = robust_limit(data)
    else:
        vmax = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
    h, w = data.shape
    fig, ax = plt.subplots(figsize=(5.5, 5.5 * h / w + 0.6), dpi=120)
    show_no_signal(ax, data.shape)
    im = ax.imshow(np.ma.masked_invalid(data), cmap=no_signal_colours(cmap),
                   vmin=-vmax if signed else 0.0, vmax=vmax, interpolation="nearest",
                   zorder=1)
    ax.set_title(title, fontsize=10)
    ax.set_axis_off()
    saturated = finite.size and np.abs(finite).max() > vmax
    bar = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04,
                       extend=("both" if signed else "max") if saturated else "neither")
    bar.set_label(label)
    fig.tight_layout()
    save_figure(fig, path, metadata)


def save_figure(fig, path, metadata: dict | None = None) -> None:
    """Save a matplotlib figure as PNG atomically, with ``metadata`` as its description."""
    import matplotlib.pyplot as plt

    info = {"Software": "dopplertof"}
    if metadata:
        info["Description"] = json.dumps(metadata, default=_json_default)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", metadata=info)
    plt.close(fig)


def write_image(path, image: np.ndarray, metadata: dict | None = None, **png_kwargs) -> None:
    """Write by extension: .exr (float32), .npy (raw array), .png (signed preview)."""
    ext = check_output_path(path)
    if ext == ".npy":
        write_npy(path, image)
    elif ext == ".exr":
        write_exr(path, image, metadata)
    else:
        write_png(path, image, metadata=metadata, **png_kwargs)


def read_toml(path, error=ValueError) -> dict:
    """A TOML file's tables; an unreadable or malformed file raises ``error`` with one
    line naming it."""
    try:  # Python 3.11+
        import tomllib
    except ModuleNotFoundError:  # pragma: no cover - Python < 3.11
        import tomli as tomllib

    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise error(f"{path}: malformed TOML: {e}") from None
    except OSError as e:
        raise error(f"{path}: cannot read: {e}") from None
