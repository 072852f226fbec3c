"""Where experiments come from: ROS bags, CSV and MATLAB tables, NetCDF experiment files,
their time stamps and motion-capture poses, and the simulator of thesis-like runs.
"""

from .bag_reading import (
    BAG_SUFFIXES,
    READ_ERRORS,
    bag_format,
    header_stamp,
    open_bag,
    receive_time_for_zero,
    typestore,
)
from .bag_writer import (
    BagMessage,
    bag_messages,
    bag_truth,
    pose_path,
    stamped_header,
    write_bag,
    write_messages,
)
from .bags import MESSAGE_TYPES, read_bag
from .experiment import (
    CHANNEL_FIELDS,
    MEASURED_PREFIX,
    MEASUREMENTS,
    RATE_FIELDS,
    STEADY_INPUT_TOLERANCE,
    STEADY_MIN_DURATION,
    STEADY_SMOOTHING,
    STEADY_YAW_FLOOR,
    STEADY_YAW_TOLERANCE,
    UNITS,
    UNLABELLED,
    Experiment,
    as_experiments,
    check_finite,
    check_values,
    detect_steady,
    numeric_array,
    read_netcdf,
    steady_smoothing,
    write_netcdf,
)
from .groups import RunGroups, as_run_groups, group_runs, read_groups, run_group
from .held import (
    HELD_MIN_LENGTH,
    HELD_MIN_RUNS,
    HELD_SPREAD,
    MIDPOINT,
    SENSOR_CLOCK,
    HeldChannel,
    held_channel,
)
from .logs import ReadOptions, ingest_logs, load_experiments, read_log, read_logs
from .matlab import mat_arrays, mat_vector
from .pose_increments import (
    BORROW_FRACTION,
    STRIDE_TOLERANCE,
    PoseObservations,
    TickPoses,
    body_displacement,
    body_increments,
    pose_observations,
    pose_samples,
    tick_poses,
)
from .pose_track import (
    POSE_FIELDS,
    POSITION_LIMIT,
    SMOOTHING_MIN_POSES,
    SMOOTHING_ORDER,
    SMOOTHING_WINDOW,
    PoseTrack,
    body_velocities,
)
from .segments import MIN_HOLD, STEP_TOLERANCE, command_segments, label_segments
from .simulate import (
    SERIES,
    NoiseSettings,
    Series,
    command_profile,
    simulate_experiment,
    simulate_series,
)
from .stamps import (
    GRID,
    GRID_TOLERANCE,
    MAX_JITTER_FRACTION,
    MAX_JITTER_STEPS,
    MAX_TICKS,
    MIN_SAMPLES,
    ONE_PER_TICK,
    PLAUSIBLE_RATES,
    UNIFORM,
    UNIFORM_TOLERANCE,
    UniformClock,
    hold_values,
    longest_run,
    sort_stamps,
    uniform_clock,
)
from .tables import (
    RATE_TOLERANCE,
    check_column_roles,
    check_columns_apply,
    check_declared_rate,
    check_sample_time,
    check_stamp_rate,
    check_unique_names,
    load_experiment,
    numeric_column,
    read_csv,
    read_csv_table,
    read_mat,
    write_csv,
)

#: What a user of this stage needs (the API reference); the other names
#: imported above serve the package's later stages.
__all__ = [
    "Experiment",
    "NoiseSettings",
    "ReadOptions",
    "load_experiments",
    "read_bag",
    "read_groups",
    "read_netcdf",
    "simulate_experiment",
    "write_bag",
    "write_csv",
    "write_netcdf",
]
