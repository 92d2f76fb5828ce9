"""The supplementary's 1-D theory as code: waveform correlations, antithetic time sampling,
MIS with antithetic samples, and the geometric-path Doppler approximation.

NumPy/SciPy only (matplotlib for ``write_figures``); independent of the renderer except for
the shared waveform definitions in ``dopplertof.modulation``.  See docs/analysis.md.
"""

from .antithetic import (
    DEFAULT_SHIFTS,
    METHODS,
    antithetic_variance,
    antithetic_variance_closed_form,
    autocorrelation,
    autocorrelation_slope,
    closed_form_table,
    convergence_study,
    draw_truncated_parameters,
    estimator_variance,
    expected_truncated_variance,
    expected_variance_over_frequency,
    find_truncated_counterexample,
    fit_log_log_slope,
    method_variance,
    mirrored_antithetic_variance,
    multi_antithetic_variance,
    optimal_two_shifts,
    periodic_variance,
    signal_mean,
    sinusoid_mean,
    sinusoid_mean_square,
    stratified_variance,
    theta_integrated_variance_closed_form,
    theta_integrated_variance_numeric,
    two_shift_variance,
    uniform_variance,
    variance_ratio,
)
from .doppler import (
    doppler_shift_difference,
    doppler_shift_from_delay,
    geometric_delay,
    geometric_doppler_shift,
    photon_delay,
    photon_doppler_shift,
)
from .figure_common import CSV_COLUMNS, DATA_FILES, FIGURE_FILES
from .figures import write_figures
from .figures_variance import (
    convergence_rates,
    local_maximum_at_half,
    theta_averaged_method_variance,
    theta_averaged_shift_variance,
)
from .mis import (
    antithetic_pdf,
    antithetic_weight,
    counterexample_variances,
    mis_antithetic_estimate,
    primal_weight,
    two_strategy_estimate,
    two_strategy_weights,
)
from .signals import PeriodicWaveform, Sinusoid, TruncatedAttenuatedSinusoid
from .waveforms import (
    correlation_from_fourier_series,
    fourier_cosine_coefficients,
    numeric_correlation,
    pulse_correlation,
    sensor_wave,
    trapezoid_sensor_wave,
)

__all__ = [name for name in dir() if not name.startswith("_")
           and name not in {"antithetic", "doppler", "figures", "figure_common",
                            "figures_variance", "mis", "signals", "waveforms", "quadrature"}]
