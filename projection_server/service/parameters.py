"""The node's parameters: one table that the node declares from and the documentation reads.

Each entry is a :class:`ParameterSpec`; :func:`descriptor` makes its ROS 2
``ParameterDescriptor`` (ranges, read-only, constraints), which ``ros2 param describe`` shows.
A string array (default ``[]``) is declared with the empty list as its value
(``ProjectionServerNode._declare_string_array``).
"""

from __future__ import annotations

from typing import Any, NamedTuple, TYPE_CHECKING

if TYPE_CHECKING:
    from rcl_interfaces.msg import ParameterDescriptor

__all__ = ['PARAMETERS', 'ParameterSpec', 'descriptor']


class ParameterSpec(NamedTuple):
    """One parameter of the node: its name, default and what its descriptor says."""

    name: str
    default: Any
    description: str
    read_only: bool = False
    range: tuple[float, float] | None = None   # inclusive (low, high) of a number
    constraints: str = ''                       # the descriptor's additional_constraints


PARAMETERS: tuple[ParameterSpec, ...] = (
    ParameterSpec('max_engines', 8, 'Most Prolog engines (live queries) at once',
                  read_only=True, range=(1, 256)),
    ParameterSpec('default_timeout', 120.0,
                  'Seconds a solution may take when the request gives 0', range=(0.001, 86400.0)),
    ParameterSpec('max_solutions', 100, 'Cap on ALL_SOLUTIONS answers when the request gives 0',
                  range=(1, 1_000_000)),
    ParameterSpec('idle_timeout', 300.0,
                  'Seconds after which an idle INCREMENTAL query is closed',
                  range=(0.001, 86400.0)),
    ParameterSpec('sandbox', True, 'Refuse goals library(sandbox) cannot prove safe'),
    ParameterSpec('bag_dir', '',
                  'Where projection bags go (empty: ~/.cache/projection_server/bags)',
                  read_only=True),
    ParameterSpec('projection_workers', 1, 'Simulation worker processes', read_only=True,
                  range=(1, 64)),
    ParameterSpec('max_bags', 1000, 'Bags kept in bag_dir; the oldest are deleted first',
                  read_only=True, range=(1, 10_000_000)),
    ParameterSpec('projection_backend', 'local',
                  'Who runs projections: local (worker processes) or ray (Ray actors)',
                  read_only=True, constraints='one of: local, ray'),
    ParameterSpec('ray_address', '',
                  'Ray cluster for projection_backend ray: auto, ray://host:port or '
                  'host:port (empty: start a local Ray instance)', read_only=True),
    ParameterSpec('kb_files', [],
                  'Turtle files added to the knowledge base at start (default: none)',
                  read_only=True),
    ParameterSpec('asset_paths', [],
                  'Directories where model files resolve, after the package assets and '
                  'before pybullet_data (default: none)', read_only=True),
    ParameterSpec('physics_engine', 'pybullet',
                  'The physics engine of a projection whose query chooses none',
                  read_only=True, constraints='one of: pybullet, mujoco'),
    ParameterSpec('robot_world', True,
                  'Read robot_description, joint_states, /tf and /tf_static for robot_world/2',
                  read_only=True),
)


def descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    """The ROS 2 descriptor of ``spec``: an integer or floating-point range by its
    default's type."""
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

    d = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
    if spec.constraints:
        d.additional_constraints = spec.constraints
    if spec.range is not None:
        low, high = spec.range
        if isinstance(spec.default, int):
            d.integer_range = [IntegerRange(from_value=low, to_value=high, step=1)]
        else:
            d.floating_point_range = [FloatingPointRange(from_value=low, to_value=high,
                                                         step=0.0)]
    return d
