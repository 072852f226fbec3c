"""The names the library's options accept and their default values: plain data, no numpy.

The one place these are written. The modules that use them import them from
here, and so does the command line's parser: ``bayes-jackal --help`` shows
the library's defaults without loading numpy, scipy, arviz or matplotlib,
and a flag's default cannot drift from the library's. Each comment names
the subpackage that uses its constants.
"""

from __future__ import annotations

__all__ = [
    "AUTOCORR_MULTIPLE",
    "AUTO_ORDER",
    "BAG_FORMATS",
    "BRIDGE_MIN_DRAWS",
    "CHANNELS",
    "CONVERSIONS",
    "DAMPING_MODEL",
    "DAMPING_MODELS",
    "DEFAULT_CHANNEL_ORDER",
    "DEFAULT_FAMILIES",
    "DISCRETISATION",
    "DISCRETISATIONS",
    "D_LAT",
    "D_LONG",
    "ENGINE",
    "ENGINES",
    "EXPERIMENT_FORMATS",
    "FAMILY",
    "FIGURE_FORMATS",
    "FILTERS",
    "FILTER_PARAMETERS",
    "GRID_METHODS",
    "GRID_POINTS",
    "HDI_PROB",
    "LOOKAHEAD",
    "MAX_GAP",
    "MAX_GAP_STEPS",
    "MAX_STEPS",
    "METHOD",
    "MIN_ESS",
    "MIN_EVIDENCE_STEPS",
    "NOISE",
    "NOISE_MAX_STEPS",
    "NOISE_SHARING",
    "OPTIONAL",
    "POSE_NOISE",
    "POSE_ROLES",
    "POSE_TIME",
    "REPORT_FORMATS",
    "REQUIRED",
    "RESIDUAL_CHANNELS",
    "RESIDUAL_LAGS",
    "ROLES",
    "SEGMENT",
    "SENSOR",
    "SENSOR_MODELS",
    "SENSOR_PRECISIONS",
    "SENSOR_SMOOTHNESS",
    "SERIES_COUNTS",
    "SERIES_ENGINES",
    "SHARED_NOISE",
    "SHORT_MEMORY",
    "SIMULATED_NOISE",
    "STATE_ESTIMATION",
    "STEADY",
    "THESIS_CHANNEL",
    "VELOCITIES",
    "VELOCITY_COMMAND",
    "WALKERS",
    "WHEEL_COMMAND",
]

# -- noise families (the registry of their classes is bayes_jackal.model.FAMILIES,
#    the one list of them; ``compare`` ranks all of it by default)
#: Family of ``sample`` and of a simulated run's process noise (``--family``).
FAMILY = "gaussian"
#: Families ``analyse`` compares (``workflow.DEFAULT_FAMILIES``): coloured or not.
DEFAULT_FAMILIES = ("white", "gaussian")
#: The short-memory family ``analyse`` adds by default where white beats gaussian: a
#: colour of a few samples (a physics engine's, a vibration's) that gaussian's
#: smooth kernel fits worse than white does (issue 37, item 14). Not compared
#: always: on the Gaussian demo its chain needs ~10,000 steps (tau ~200), 165 s.
SHORT_MEMORY = "exponential"

# -- the model and its likelihood (model.physics, likelihood)
#: State channels in state-vector order (``physics.CHANNELS``).
CHANNELS = ("vx", "vy", "yaw")
#: Order of the default channels: the thesis' yaw rate, then vx and vy.
DEFAULT_CHANNEL_ORDER = ("yaw", "vx", "vy")
#: Discretisations of the continuous model, zero-order hold (eq. 6-6) or forward
#: Euler (6-5), and the default.
DISCRETISATIONS = ("zoh", "euler")
DISCRETISATION = "zoh"
#: Sensor-noise footprints (``--sensor-noise``) and the default.
SENSOR_MODELS = ("ma1", "diagonal")
SENSOR = "ma1"
#: Whether the likelihood takes each run's steady window only (``--steady``, the
#: thesis' crop) or every sample, transients included (the default: the model
#: covers them, and they identify the damping's scale).
STEADY = False
#: How the damping depends on the state (``--damping``): one damping (the
#: default), or log d = log d_ref + log(r) (v - v_ref) / (v_max - v_min) over the
#: runs' segments, v each segment's speed (likelihood.ResidualLikelihood).
DAMPING_MODELS = ("constant", "speed")
DAMPING_MODEL = DAMPING_MODELS[0]
#: Likelihood engines (``--engine``) and the default.
ENGINES = ("fast", "exact", "whittle")
ENGINE = "fast"
#: Noise parameters of pooled experiments (``--noise``): shared, each experiment's own,
#: or shared with one width for every channel (``ParameterLayout.shared_width``).
NOISE_SHARING = ("shared", "per-experiment", "one-width")
#: ... shared by default (``ResidualLikelihood.shared_noise``).
SHARED_NOISE = True
NOISE = NOISE_SHARING[0 if SHARED_NOISE else 1]

# -- the sampler (inference.SamplerSettings)
#: Step cap of each chain (``--max-steps``); a chain that reaches it is NOT CONVERGED.
MAX_STEPS = 20_000
#: Step cap of each family's chain of a noise series (``noise --max-steps``): on
#: white noise a coloured family's width is not identified and its chain never
#: converges (measured: 8 min per family at MAX_STEPS on 1,000 samples), while the
#: chains of a coloured series converge within it (bayes_jackal.noise.characterisation).
NOISE_MAX_STEPS = 5_000
#: Fewest draws bridge sampling takes (the first half fits its proposal).
BRIDGE_MIN_DRAWS = 8
#: Fewest steps of a chain whose evidence is estimated (compare, analyse, noise):
#: the chain keeps at least its second half, thinned to no fewer than BRIDGE_MIN_DRAWS
#: draws of each walker (bayes_jackal.inference.chains).
MIN_EVIDENCE_STEPS = 2 * BRIDGE_MIN_DRAWS
#: Ensemble size (``--walkers``); 0: max(32, 4 x parameters).
WALKERS = 0
#: A chain stops once longer than this many autocorrelation times (emcee's advice) ...
AUTOCORR_MULTIPLE = 50.0
#: ... with at least this bulk and tail effective sample size for every parameter
#: (arviz's ess, walkers as chains; Vehtari et al. 2021 ask 400 before trusting r_hat).
MIN_ESS = 400

# -- the thesis' grid search and residual analysis (thesis)
#: The channel of the thesis' grid search and residual analysis: the yaw rate.
THESIS_CHANNEL = "yaw"
#: Grid-search criteria (``grid --method``) and the default.
GRID_METHODS = ("onestep", "simulation")
METHOD = "onestep"
#: Values per damping axis of each criterion's default grid, log-spaced over
#: the profile's prior range (``thesis.prior_grid``): the thesis' counts, its
#: one-step grid's 1..1000 step 1 (O(1) per point) and its simulation grid's
#: 10..1000 step 10 (a simulation per point).
GRID_POINTS = {"onestep": 1000, "simulation": 100}
#: The thesis' damping (d_lat, d_long) [N s/m] of the Jackal: the simulator's
#: truth and the model of the residual analysis by default, times the robot's
#: mass / the Jackal's (``model.mass_scaled_damping``).
D_LAT = 110.0
D_LONG = 30.0
#: Lags of the Ljung-Box test and of the sigma_h fit (thesis ch. 7-3).
RESIDUAL_LAGS = 30
#: Channels of the residual analysis by default.
RESIDUAL_CHANNELS = (THESIS_CHANNEL,)

# -- simulated runs (io.simulate)
#: Runs per series of a simulated data set: the thesis' 10 x v1 + 5 x v2.
SERIES_COUNTS = {"v1": 10, "v2": 5}
#: ``simulate.NoiseSettings`` defaults: kernel width [s], process and sensor
#: noise sd of (vx, vy, yaw) per step [m/s, m/s, rad/s].
SIMULATED_NOISE = {
    "width": 0.047,
    "sigma_c": (0.005, 0.005, 0.01),
    "sigma_n": (0.003, 0.003, 0.005),
}
#: File formats of a simulated run (``simulate --format``); the first is the default.
EXPERIMENT_FORMATS = ("nc", "csv")
#: Formats of a simulated run's bag (``simulate --bag``): ROS1 ``.bag``, ROS2 ``.mcap``.
BAG_FORMATS = ("ros1", "ros2")
#: Motion-capture noise of a simulated run's bag (``simulate --pose-noise``,
#: ``bag_writer.POSE_NOISE``): position sd per axis [m] and heading sd [rad], a
#: lab system's (OptiTrack, Vicon: 0.1-0.5 mm).
POSE_NOISE = (0.5e-3, 0.002)
#: Ways of turning a velocity command (v, w) into wheel speeds (``robot.CONVERSIONS``).
CONVERSIONS = ("ros", "thesis")

# -- reading logs (io)
#: Columns every experiment has, and those it may have.
REQUIRED = ("t", "yaw_rate", "omega_r", "omega_l")
OPTIONAL = ("vx", "vy")
#: A table's motion-capture pose, world x, y [m] and heading [rad] (all or none).
POSE_ROLES = ("x", "y", "heading")
#: The pose's own time [s] where it has its own (a MATLAB struct ``pose.t``);
#: the table's ``t`` otherwise.
POSE_TIME = "pose_t"
#: A table's command: the body velocity v [m/s] and yaw rate w [rad/s] (cmd_vel) ...
VELOCITY_COMMAND = ("cmd_v", "cmd_w")
#: ... or the commanded wheel speeds [rad/s]; each pair all or none.
WHEEL_COMMAND = ("cmd_omega_r", "cmd_omega_l")
#: A table's label of the run's segment (command step) at each row, integer or text.
SEGMENT = "segment"
#: Column roles a file's columns can be mapped to (``columns=``, ``--column``).
ROLES = (*REQUIRED, *OPTIONAL, *POSE_ROLES, POSE_TIME, *VELOCITY_COMMAND, *WHEEL_COMMAND, SEGMENT)
#: What a table's vx, vy columns are (``velocities=``, ``--velocities``): measured by
#: a sensor, or derived from poses the table lacks (the model is the same; a
#: posterior then warns); the first is the default.
VELOCITIES = ("measured", "derived")
#: Longest tolerated dropout of a bag's topic [s] (``--max-gap``): 18 IMU samples at 72 Hz.
MAX_GAP = 0.25
#: Longest gap of an experiment file filled by interpolation [sample steps].
MAX_GAP_STEPS = 5

# -- outputs (dem, report)
#: The embedding order of ``export_prior(order=None)`` where the family allows it.
AUTO_ORDER = 2
#: Smoothness of the white sensor noise in Pi_z [time bins]: SPM's default
#: ``E.s``; its derivative has the variance of white noise's one-step
#: difference, 2 sigma_n^2 per bin^2 (the default ``sensor_smoothness`` of
#: ``export_prior``).
SENSOR_SMOOTHNESS = 0.5
#: Figure files a report can write beside it (``--formats``).
FIGURE_FORMATS = ("png", "svg")
#: Figure files written beside a report unless more are asked for
#: (``--formats png,svg``): each figure is embedded as PNG in any case, and
#: its SVG took a third of a report's drawing time (the demo's: 5 of 16 s).
REPORT_FORMATS = ("png",)

# -- state estimation with a prior (filters)
#: The filters (``filter --filters``): the white and coloured Kalman
#: filters, and the generalised filter (``state_estimation.FILTERS``).
FILTERS = ("kalman", "kalman-coloured", "generalised")
#: The filters' noise parameters: at the posterior means, or averaged over
#: the prior's draws (``bayes_jackal.filters.PARAMETERS``); the first is the default.
FILTER_PARAMETERS = ("plug-in", "averaged")
#: Pi_z of the generalised filter: embedded white noise, or the prior's
#: Gaussian sensor smoothness (the generalised filter's ``sensor_precision``); the
#: first is the default.
SENSOR_PRECISIONS = ("white", "exported")
#: Samples after t_k in the generalised filter's embedding: 0, causal
#: (the generalised filter's ``lookahead``).
LOOKAHEAD = 0
#: Whether ``analyse`` scores the filters on each run left out of the prior
#: (``analyse --no-state-estimation`` turns it off; ``leave_one_out``).
STATE_ESTIMATION = True

# -- a bare noise series (likelihood.series_likelihood, noise)
#: Likelihood engines of a noise series (``noise --engine``); the first is the default.
SERIES_ENGINES = ("fast", "exact")


#: Credible mass of the reported highest-density intervals (arviz's default).
HDI_PROB = 0.94
