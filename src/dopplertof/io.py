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
    vmax = float(np.percentile(np.abs(finite), 99.5)) if finite.size else 1.0
    vmax = vmax if vmax > 0 else 1.0
    if not signed:
        vmax = float(finite.max()) if finite.size and finite.max() > 0 else 1.0
    h, w = data.shape
    fig, ax = plt.subplots(figsize=(5.5, 5.5 * h / w + 0.6), dpi=120)
    im = ax.imshow(data, cmap=cmap, vmin=-vmax if signed else 0.0, vmax=vmax,
                   interpolation="nearest")
    ax.set_title(title)
    ax.set_axis_off()
    bar = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
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
