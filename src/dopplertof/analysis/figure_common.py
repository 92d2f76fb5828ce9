"""What the supplementary's figures share: their file names, labels and colours, the
settings of a full or quick run, and the atomic writing of a figure or a text file."""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass

from ..io import atomic_path
from ..image_files import fit_figure

PI = math.pi

#: file names written by ``write_figures``, in order
FIGURE_FILES = (
    "doppler_geometric_vs_photon.png",
    "waveform_correlations.png",
    "antithetic_shift_variance.png",
    "antithetic_variance_ratio.png",
    "truncated_attenuated_variance.png",
    "higher_frequency_variance.png",
    "two_antithetic_shifts.png",
    "convergence_rates.png",
    "mirrored_stratified_shift.png",
    "closed_forms.png",
    "mis_antithetic.png",
)
DATA_FILES = ("closed_forms.csv", "rates.json")
#: width (rad) of the unit-mean box pulse standing in for the delta illumination in Fig. 2
DELTA_PULSE_WIDTH = 1e-3
CSV_COLUMNS = ("omega", "method", "closed_form", "numeric")

METHOD_LABELS = {
    "uniform": "uniform (1 sample)",
    "stratified": "stratified (2 strata)",
    "antithetic": "shifted antithetic (a = 1/2)",
    "antithetic_mirror": "mirrored antithetic (a = 0)",
    "periodic": "periodic (N antithetic samples)",
}
METHOD_COLORS = {"uniform": "tab:gray", "stratified": "tab:green", "antithetic": "tab:blue",
                 "antithetic_mirror": "tab:orange", "periodic": "tab:blue"}


@dataclass(frozen=True)
class Settings:
    """Grid sizes; ``Settings.for_mode(quick)`` picks the full or the quick set."""

    shifts: int                # points on the shift axis a in [0, 1]
    ratio_grid: int            # omega x theta grid of Fig. 4
    truncated_omegas: int      # omegas of the Eq. (26) expectation
    truncated_shifts: int
    truncated_draws: int       # Monte Carlo draws of the Eq. (26) parameters
    two_shift_grid: int        # a x b grid of Fig. 7
    sample_counts: tuple       # N of Fig. 8
    fit_from: int              # smallest N in the slope fit
    omega_nodes: int           # Gauss-Legendre nodes over omega in Fig. 8
    thetas: int                # equispaced theta points for averages over theta
    closed_form_omegas: int    # rows per method in closed_forms.csv
    mis_tilts: int
    mis_nodes: int             # quadrature nodes per axis for Sec. 4.2
    speeds: int
    dpi: int
    layout: object             # matplotlib layout engine; None (fixed margins) is ~2x faster

    @staticmethod
    def for_mode(quick: bool) -> "Settings":
        if quick:
            return Settings(shifts=41, ratio_grid=61, truncated_omegas=4, truncated_shifts=21,
                            truncated_draws=64, two_shift_grid=31,
                            sample_counts=(1, 2, 4, 8, 16), fit_from=4, omega_nodes=12,
                            thetas=8, closed_form_omegas=8, mis_tilts=5, mis_nodes=24,
                            speeds=25, dpi=60, layout=None)
        return Settings(shifts=201, ratio_grid=241, truncated_omegas=16, truncated_shifts=51,
                        truncated_draws=512, two_shift_grid=101,
                        sample_counts=(1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64), fit_from=4,
                        omega_nodes=24, thetas=16, closed_form_omegas=64, mis_tilts=13,
                        mis_nodes=48, speeds=121, dpi=110, layout="constrained")


# --------------------------------------------------------------------------- writing

def new_figure(settings, width, height):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), layout=settings.layout)
    if settings.layout is None:
        figure.subplots_adjust(left=0.07, right=0.97, bottom=0.1, top=0.84, wspace=0.3,
                               hspace=0.45)
    FigureCanvasAgg(figure)
    return figure


def write_atomically(path: pathlib.Path, write):
    """Call ``write(temporary_path)``, then move the result onto ``path`` in one step
    (the package's one atomic writer, :func:`dopplertof.io.atomic_path`)."""
    with atomic_path(path) as temporary:
        write(temporary)
    return path


def write_figure(figure, path: pathlib.Path, dpi: int):
    """``figure`` fitted to what it draws (:func:`dopplertof.image_files.fit_figure`: no title,
    label or legend past an edge), saved atomically as PNG."""
    figure.set_dpi(dpi)  # (measured at the resolution it is saved at: text sizes round)
    fit_figure(figure)
    return write_atomically(path, lambda tmp: figure.savefig(tmp, format="png", dpi=dpi))


def write_text(path: pathlib.Path, text: str):
    def write(tmp):
        with open(tmp, "w", encoding="utf-8", newline="") as stream:
            stream.write(text)

    return write_atomically(path, write)


def centered_extent(x, y):
    """imshow extent that puts pixel centres on the sample grids x and y (uniform)."""
    half_x, half_y = 0.5 * (x[1] - x[0]), 0.5 * (y[1] - y[0])
    return (x[0] - half_x, x[-1] + half_x, y[0] - half_y, y[-1] + half_y)


def shift_legend_handles(omegas, colors, thetas, styles):
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=c, label=f"ω = {w / PI:.2g}π") for w, c in zip(omegas, colors)]
    handles += [Line2D([], [], color="k", linestyle=s, label=f"θ = {t / PI:.2g}π")
                for t, s in zip(thetas, styles)]
    return handles
