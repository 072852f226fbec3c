"""How posteriors and evidence are made: emcee chains, their moves and start,
bridge and nested sampling, and noise-filter families compared by evidence.
"""

from .chains import (
    BufferedHDFBackend,
    Chain,
    SamplerSettings,
    autocorrelation_time,
    effective_sizes,
    run_chain,
)
from .comparison import (
    COLOURED_LOG_BF,
    WHITE_LOG_BF,
    Comparison,
    colour_verdict,
    compare,
    compare_families,
    compare_groups,
    width_floor,
)
from .evidence import bridge_sampling, evidence_strength, integrated_time, nested_sampling
from .executors import (
    Background,
    DaskExecutor,
    Executor,
    Pending,
    ProcessExecutor,
    SerialExecutor,
    executor_for,
    in_processes,
)
from .hierarchy import (
    DAMPING_NAMES,
    FROM_SCALE_RATIO,
    POPULATION_STRUCTURES,
    SLOPE_SD,
    TAU_RANGE,
    TO_SCALE_RATIO,
    Hierarchy,
    UnitPosterior,
    unit_posterior,
)
from .importance import ImportanceSample, importance_posterior
from .map_search import (
    block_proposals,
    climb,
    find_map,
    laplace_walkers,
    ridge_mixture,
    scan_posterior,
)
from .moves import (
    GROUP_WEIGHT,
    INDEPENDENCE_WEIGHT,
    MIN_MATCHED_EFFICIENCY,
    MIN_PROPOSAL_EFFICIENCY,
    SHARED_WEIGHT,
    BlockT,
    BoundedLaplace,
    GroupGrid,
    GroupMove,
    IndependenceMove,
    LaplaceApproximation,
    MixtureApproximation,
    Start,
    as_laplace,
    as_mixture,
    ensemble_moves,
    moment_matched,
    proposal_efficiency,
)
from .options import FitOptions
from .population_analysis import (
    POPULATION_DRAWS,
    SENSITIVITY_TAU_RANGES,
    Population,
    UnitPlan,
    plan_units,
    population,
    population_posterior,
    unit_files,
)
from .sampler_warnings import ConvergenceWarning, KeptWarnings, keep_warnings
from .sampling import run_identity, sample, sample_posterior
from .starts import profile_starts, series_profile

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "Comparison",
    "ConvergenceWarning",
    "DaskExecutor",
    "FitOptions",
    "Population",
    "ProcessExecutor",
    "SamplerSettings",
    "SerialExecutor",
    "compare",
    "compare_groups",
    "population",
    "sample",
]
