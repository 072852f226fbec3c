"""Self-contained HTML reports and every figure in them."""

from .estimate_plots import SHOWN_SECONDS, plot_state_estimates, shown_window
from .figures import DPI, ReportFigures, figure_formats, formats_text, slug
from .grid_plots import plot_grid, save_grid_plot
from .noise_page import (
    NOISE_HEADER,
    NOISE_REPORT,
    noise_rows,
    render_noise_report,
    write_noise_report,
)
from .noise_plots import (
    noise_predictive_bands,
    plot_noise_autocorrelation,
    plot_noise_spectrum,
    plot_noise_widths,
    replicate_statistics,
)
from .page import (
    LAGS,
    draw_posterior_sections,
    posterior_sections,
    read_posteriors,
    render_report,
    report_page,
    save_report,
    write_page,
    write_report,
)
from .plots import (
    plot_criticism,
    plot_damping,
    plot_model_fit,
    plot_residuals,
    plot_sigma_h,
    plot_traces,
)
from .population_plots import plot_population, save_population_plot
from .predictive_plots import (
    band_statistics,
    plot_autocorrelation,
    plot_spectrum,
    predictive_bands,
)
from .sections import (
    html_table,
    population_highlight,
    population_section,
    state_estimation_highlight,
    state_estimation_section,
)

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "plot_autocorrelation",
    "plot_population",
    "write_noise_report",
    "write_report",
]
