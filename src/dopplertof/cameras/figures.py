"""Figures of the cameras: wiggling against distance, and one scene through several
cameras side by side."""

from __future__ import annotations

import numpy as np

from .. import file_formats, previews

from .. import image_files
from .demodulate import calibration_tables, wiggling_curves


def write_wiggling(path, preset) -> dict:
    """The noise-free depth error of ``preset`` against distance (analytic, from the
    modulation's correlation) as a PNG, and beside it (.json) the curves and the
    calibration tables; returns the numbers."""
    distances, per_frequency, raw, reported = wiggling_curves(preset)
    plt = image_files.pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 4.3), dpi=120)
    for f, error in per_frequency.items():
        ax.plot(distances, error * 1e3, lw=0.8, alpha=0.6, label=f"{f:g} MHz alone, uncalibrated")
    ax.plot(distances, raw * 1e3, "k", lw=1.5, label="reported depth, uncalibrated")
    calibrated = preset.reconstruction["wiggling_calibration"]
    ax.plot(distances, reported * 1e3, "C3--", lw=1.5,
            label="reported depth, " + ("with the camera's table" if calibrated
                                        else "as the camera reports it (no table)"))
    ax.set_xlabel("distance (m)")
    ax.set_ylabel("depth error (mm)")
    ax.set_title(f"{preset.name}: wiggling ({preset.waveform} modulation), noise-free", fontsize=10)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2,
              frameon=False)  # (below the axes: the curves fill them)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    image_files.save_figure(fig, path)
    numbers = {"camera": preset.name, "waveform": preset.waveform,
               "calibration_applied": calibrated,
               "max_abs_error_uncalibrated_m": float(np.max(np.abs(raw))),
               "max_abs_error_reported_m": float(np.max(np.abs(reported))),
               "distances_m": distances.tolist(), "error_uncalibrated_m": raw.tolist(),
               "error_reported_m": reported.tolist(),
               "calibration_tables": calibration_tables(preset)}
    file_formats.write_json(str(path)[:-4] + ".json", numbers)
    return numbers


def write_camera_comparison(path, results, title: str) -> dict:
    """One row per camera: range error, amplitude and (heterodyne) velocity, masked
    pixels (NaN) hatched on magenta as in every preview (white would read as zero error);
    beside it (FIG.json) each camera's numbers: its error statistics and masked pixels.
    Returns the numbers."""
    plt = image_files.pyplot()
    rows = len(results)
    fig, axes = plt.subplots(rows, 3, figsize=(10.5, 2.9 * rows), dpi=100, squeeze=False)
    errors = [r.depth - r.depth_gt for r in results]
    limit = max(float(np.nanpercentile(np.abs(e), 95)) if np.isfinite(e).any() else 0.0
                for e in errors) or 0.01

    def show(ax, data, cmap, **scale):
        image_files.show_no_signal(ax, data.shape)
        return ax.imshow(np.ma.masked_invalid(data), cmap=image_files.no_signal_colours(cmap),
                         interpolation="nearest", zorder=1, **scale)

    for row, result, error in zip(axes, results, errors):
        name = result.preset.name
        shown = show(row[0], error, "PuOr_r", vmin=-limit, vmax=limit)
        row[0].set_title(f"{name}: range error (m)\n"
                         + masked_caption(error, result.summary["depth"]["masked_pixels"]),
                         fontsize=8)
        fig.colorbar(shown, ax=row[0], fraction=0.046,
                     extend=previews.colorbar_extend(error, -limit, limit))
        shown = show(row[1], result.reconstruction.amplitude, "gray")
        row[1].set_title(f"{name}: amplitude (DN)", fontsize=8)
        fig.colorbar(shown, ax=row[1], fraction=0.046)
        velocity = result.reconstruction.velocity
        if velocity is not None:
            v = float(np.nanmax(np.abs(result.velocity_gt))) * 1.25 or 1.0
            shown = show(row[2], velocity, "RdBu_r", vmin=-v, vmax=v)
            row[2].set_title(f"{name}: radial velocity (m/s)\n"
                             f"NaN (hatched): {np.count_nonzero(np.isnan(velocity))} px",
                             fontsize=8)
            fig.colorbar(shown, ax=row[2], fraction=0.046,
                         extend=previews.colorbar_extend(velocity, -v, v))
        else:
            row[2].text(0.5, 0.5, "no velocity\n(homodyne frames only)", ha="center",
                        va="center", fontsize=8, transform=row[2].transAxes)
        for ax in row:
            ax.set_axis_off()
    fig.suptitle(title, fontsize=10)
    fig.text(0.5, 0.005, previews.NO_SIGNAL_NOTE, ha="center", va="bottom", fontsize=7)
    fig.tight_layout(rect=(0, 0.02, 1, 1 - 0.3 / fig.get_figheight()))  # (the suptitle's)
    image_files.save_figure(fig, path)
    numbers = {"title": title, "cameras": [_comparison_numbers(r, e)
                                           for r, e in zip(results, errors)]}
    file_formats.write_json(str(path)[:-4] + ".json", numbers)
    return numbers


def masked_caption(error, masked_by: dict, width: int = 40) -> str:
    """The caption of a range-error panel: its masked (NaN, hatched) pixels of all, and each
    mask's count that is not 0 (a pixel can be in several), wrapped to ``width`` between
    the masks (no-break spaces within one)."""
    import textwrap

    masked = int(np.count_nonzero(~np.isfinite(error)))
    reasons = [f"{reason} {count}".replace(" ", "\u00a0")
               for reason, count in masked_by.items() if count]
    text = f"masked (hatched): {masked} of {error.size} px"
    return textwrap.fill(text + (": " + ", ".join(reasons) if reasons else ""), width)


def _comparison_numbers(result, error) -> dict:
    """One camera's row of the comparison: its summary's errors and the pixels masked
    in its range error (NaN: hatched), and each mask's count (``masked_by``, the summary's:
    a pixel can be in several)."""
    summary = result.summary
    return {"camera": result.preset.name, "errors": summary["errors"],
            "masked_pixels": int(np.count_nonzero(~np.isfinite(error))),
            "masked_by": summary["depth"]["masked_pixels"],
            "pixels": int(error.size), "mixed_footprints": summary["mixed_footprints"],
            "saturated_pixels": summary["noise"]["saturated_pixels"]}
