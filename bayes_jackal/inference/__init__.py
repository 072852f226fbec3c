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
)
from .evidence import bridge_sampling, evidence_strength, integrated_time, nested_sampling
from .executors import (
    DaskExecutor,
    Executor,
    ProcessExecutor,
    SerialExecutor,
    executor_for,
    in_processes,
)
from .map_search import climb, find_map, laplace_walkers, ridge_mixture, scan_posterior
from .moves import (
    INDEPENDENCE_WEIGHT,
    MIN_MATCHED_EFFICIENCY,
    MIN_PROPOSAL_EFFICIENCY,
    IndependenceMove,
    LaplaceApproximation,
    MixtureApproximation,
    Start,
    as_mixture,
    ensemble_moves,
    moment_matched,
    proposal_efficiency,
)
from .sampler_warnings import ConvergenceWarning, KeptWarnings, keep_warnings
from .sampling import chain_path, run_identity, sample, sample_posterior
from .starts import profile_starts, series_profile

__all__ = [
    "COLOURED_LOG_BF",
    "INDEPENDENCE_WEIGHT",
    "MIN_MATCHED_EFFICIENCY",
    "MIN_PROPOSAL_EFFICIENCY",
    "WHITE_LOG_BF",
    "BufferedHDFBackend",
    "Chain",
    "Comparison",
    "ConvergenceWarning",
    "DaskExecutor",
    "Executor",
    "IndependenceMove",
    "KeptWarnings",
    "LaplaceApproximation",
    "MixtureApproximation",
    "ProcessExecutor",
    "SamplerSettings",
    "SerialExecutor",
    "Start",
    "as_mixture",
    "autocorrelation_time",
    "bridge_sampling",
    "chain_path",
    "climb",
    "colour_verdict",
    "compare",
    "compare_families",
    "compare_groups",
    "effective_sizes",
    "ensemble_moves",
    "evidence_strength",
    "executor_for",
    "find_map",
    "in_processes",
    "integrated_time",
    "keep_warnings",
    "laplace_walkers",
    "moment_matched",
    "nested_sampling",
    "profile_starts",
    "proposal_efficiency",
    "ridge_mixture",
    "run_chain",
    "run_identity",
    "sample",
    "sample_posterior",
    "scan_posterior",
    "series_profile",
]
