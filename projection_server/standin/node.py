"""``projection_standin_robot``: the stand-in robot as a ROS 2 node, as a real one is wired.

It publishes what a robot and its perception publish, from its own world
(:mod:`.world`), stamped with the node's clock:

* ``/robot_description`` (``std_msgs/String``; reliable, transient local, depth 1): the
  robot's URDF, as robot_state_publisher publishes it, its meshes
  ``package://<description_package>/...``;
* ``/joint_states`` (``sensor_msgs/JointState``) at ``publish_rate``: every joint neither
  fixed nor mimic;
* ``/tf_static`` (transient local): the base in ``world_frame`` and every fixed joint;
  ``/tf`` (volatile, depth 100) at ``publish_rate``: every moving joint, parent link ->
  child link, and the object's frame in ``world_frame``, as perception would publish it.
  The object's true properties are on no topic.

It serves ``~/execute_plan`` (``projection_interfaces/action/ExecutePlan``: a plan in the
plan language, feedback as each step begins, the events it observed) and ``~/reset_world``
(``projection_interfaces/srv/ResetWorld``: a new world from a seed, the truth drawn in the
response). Example::

    projection_standin_robot --ros-args -p seed:=3
    ros2 action send_goal --feedback /standin_robot/execute_plan \\
        projection_interfaces/action/ExecutePlan "{plan: '[close_gripper(5)]'}"
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any

from geometry_msgs.msg import TransformStamped
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
import rclpy
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from projection_interfaces.action import ExecutePlan
from projection_interfaces.srv import ResetWorld
from projection_server.errors import ErrorKind, ProjectionError
from projection_server.service.spin import run_node
from projection_server.standin.plan_text import parse_plan
from projection_server.standin.world import (Outcome, ROBOT_BASE, StandinConfig,
                                             StandinError, StandinWorld, WorldState,
                                             world_json)

__all__ = ['StandinRobotNode', 'main']

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
TF = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.VOLATILE)
RANGES = {   # parameter -> (StandinConfig field, description)
    'friction_range': ('friction', "the object's true friction coefficient is drawn from "
                       '[low, high]'),
    'mass_range': ('mass', "the object's true mass [kg] is drawn from [low, high]"),
    'breaking_force_range': ('breaking_force', "the object's true breaking force [N] is "
                             'drawn from [low, high]'),
    'object_x_range': ('x', "the object's centre x [m] on the table, in world_frame"),
    'object_y_range': ('y', "the object's centre y [m] on the table, in world_frame"),
    'object_yaw_range': ('yaw', "the object's long axis from world x [rad]"),
}


class StandinRobotNode(Node):
    """The node: parameters, publishers, the action and the service, over a
    :class:`~projection_server.standin.world.StandinWorld`."""

    def __init__(self) -> None:
        super().__init__('standin_robot')
        defaults = StandinConfig()
        self.declare_parameter('seed', 0, ParameterDescriptor(
            description='the world at start is the one a reset with this seed draws',
            read_only=True))
        for name, (key, description) in RANGES.items():
            # Dynamically typed: '[4, 14]' is an integer array, '[4.0, 14.0]' a double one.
            self.declare_parameter(name, list(getattr(defaults, key)), ParameterDescriptor(
                description=description + ' (two numbers)', read_only=True,
                dynamic_typing=True))
        self.declare_parameter('joint_spread', defaults.joint_spread, ParameterDescriptor(
            description='the arm starts (and after a reset) within this many rad of the '
            "knowledge base's home pose, in each joint, but not at it", read_only=True,
            floating_point_range=[FloatingPointRange(from_value=0.25, to_value=1.0)]))
        self.declare_parameter('physics_factor', defaults.physics_factor, ParameterDescriptor(
            description="times the projection's physics rate and solver iterations the "
            'world runs at', read_only=True,
            integer_range=[IntegerRange(from_value=1, to_value=8, step=1)]))
        self.declare_parameter('publish_rate', 100.0, ParameterDescriptor(
            description='Hz of /joint_states and /tf', read_only=True,
            floating_point_range=[FloatingPointRange(from_value=1.0, to_value=500.0)]))
        self.declare_parameter('real_time', defaults.real_time, ParameterDescriptor(
            description='pace a plan to the wall clock (false: as fast as it simulates)',
            read_only=True))
        for name, value, description in (
                ('world_frame', 'map', 'the frame of the base and the object on /tf'),
                ('object_name', defaults.object_name, "the object's name in plans and events"),
                ('object_frame', defaults.object_frame, "the object's frame on /tf (plans "
                 'may name the object by it too)'),
                ('description_package', 'franka_panda', 'the package of the meshes in '
                 '/robot_description: package://<it>/meshes/...'),
                ('bag_dir', '', 'keep each execution as a bag here (empty: none kept)')):
            self.declare_parameter(name, value, ParameterDescriptor(
                description=description, read_only=True))
        value = self.get_parameter
        self.world_frame = value('world_frame').value
        config = StandinConfig(
            **{key: _range(name, value(name).value) for name, (key, _) in RANGES.items()},
            joint_spread=value('joint_spread').value,
            physics_factor=value('physics_factor').value,
            state_hz=max(100.0, value('publish_rate').value),
            real_time=value('real_time').value, object_name=value('object_name').value,
            object_frame=value('object_frame').value, bag_dir=value('bag_dir').value)
        self.world = StandinWorld(config)
        self.world.reset(value('seed').value)
        self.world.warm_up()
        tree = self.world.tree

        self.description_pub = self.create_publisher(String, '/robot_description', LATCHED)
        self.static_pub = self.create_publisher(TFMessage, '/tf_static', LATCHED)
        self.tf_pub = self.create_publisher(TFMessage, '/tf', TF)
        self.joints_pub = self.create_publisher(JointState, '/joint_states', 10)
        self.description_pub.publish(String(
            data=tree.description(value('description_package').value)))
        now = self.get_clock().now().to_msg()
        base = (self.world_frame, tree.root, ROBOT_BASE, (0.0, 0.0, 0.0, 1.0))
        self.static_pub.publish(TFMessage(transforms=[
            _transform(now, *t) for t in [base, *tree.static_transforms()]]))

        # The timer publishes the latest state while a plan runs in the action's thread:
        # the simulation and the publishing never wait for each other.
        self.create_timer(1.0 / value('publish_rate').value, self._publish,
                          callback_group=MutuallyExclusiveCallbackGroup())
        self._actions = ActionServer(
            self, ExecutePlan, '~/execute_plan', self._execute,
            goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=lambda goal: CancelResponse.ACCEPT,
            callback_group=ReentrantCallbackGroup())   # a second goal is told the robot is busy
        self.create_service(ResetWorld, '~/reset_world', self._reset,
                            callback_group=MutuallyExclusiveCallbackGroup())
        self.get_logger().info(
            f'stand-in robot ready: {config.object_name} at '
            f'{[round(v, 3) for v in self.world.state.object_xyz]} (seed {value("seed").value})')

    # --- topics -------------------------------------------------------------------------
    def _publish(self) -> None:
        if not self.context.ok():   # shutting down: the publishers are going away
            return
        try:
            self._publish_state(self.world.state)
        except Exception:  # noqa: BLE001 - rclpy's error of a publisher shut down under it
            if self.context.ok():
                raise

    def _publish_state(self, state: WorldState) -> None:
        stamp = self.get_clock().now().to_msg()
        joints = JointState(name=list(state.joints), position=list(state.joints.values()))
        joints.header.stamp = stamp
        self.joints_pub.publish(joints)
        config = self.world.config
        transforms = [_transform(stamp, *t) for t in self.world.tree.transforms(state.joints)]
        transforms.append(_transform(stamp, self.world_frame, config.object_frame,
                                     state.object_xyz, state.object_quaternion))
        self.tf_pub.publish(TFMessage(transforms=transforms))

    # --- the service and the action -----------------------------------------------------
    def _reset(self, request: ResetWorld.Request, response: ResetWorld.Response
               ) -> ResetWorld.Response:
        try:
            self.world.reset(request.seed)
        except ProjectionError as exc:
            response.ok, response.error = False, exc.message
            return response
        response.ok, response.world_json = True, world_json(self.world)
        self.get_logger().info(f'reset with seed {request.seed}')
        return response

    def _execute(self, goal: Any) -> ExecutePlan.Result:
        started = time.monotonic()
        try:
            plan = parse_plan(goal.request.plan)
        except ProjectionError as exc:
            outcome = Outcome(False, exc.message)
        else:
            try:
                outcome = self.world.execute(plan, _GoalObserver(goal, started))
            except Exception as exc:  # noqa: BLE001 - the goal fails, the robot serves on
                self.get_logger().error(f'executing the plan failed: {exc!r}')
                outcome = Outcome(False, f'executing the plan failed: {exc}')
        result = ExecutePlan.Result(
            ok=outcome.ok, error=outcome.error, events=outcome.events,
            timeline_json=json.dumps(outcome.timeline) if outcome.timeline else '',
            duration=time.monotonic() - started, world_time=outcome.world_time)
        if outcome.ok:
            goal.succeed()
        elif goal.is_cancel_requested:
            goal.canceled()
        else:
            goal.abort()
        self.get_logger().info(f'plan {"done" if outcome.ok else "failed"} in '
                               f'{result.duration:.2f} s: {outcome.error or outcome.events}')
        return result

    def destroy_node(self) -> None:
        self.world.close()
        super().destroy_node()


class _GoalObserver:
    """Feedback as each step begins; a cancel stops the world."""

    def __init__(self, goal: Any, started: float):
        self.goal, self.started = goal, started

    def state(self, state: WorldState) -> None:
        pass   # the node's timer publishes the world's latest state

    def step(self, index: int, total: int, text: str) -> None:
        self.goal.publish_feedback(ExecutePlan.Feedback(
            step=index, steps=total, text=text, elapsed=time.monotonic() - self.started))

    def cancelled(self) -> bool:
        return self.goal.is_cancel_requested


def _range(name: str, value: Any) -> tuple[float, float]:
    """A range parameter's [low, high], integers or floats."""
    if (not isinstance(value, (list, tuple)) or len(value) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
        raise StandinError(ErrorKind.INVALID_PARAMETERS,
                           f'{name}: two numbers [low, high], got {value!r}')
    return (float(value[0]), float(value[1]))


def _transform(stamp: Any, parent: str, child: str, xyz: Any, quaternion: Any
               ) -> TransformStamped:
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = (
        float(v) for v in xyz)
    r = t.transform.rotation
    r.x, r.y, r.z, r.w = (float(v) for v in quaternion)
    return t


def main(args=None) -> int:
    return run_node('projection_standin_robot', StandinRobotNode, lambda node: 4,
                    (ProjectionError,), args)


if __name__ == '__main__':
    sys.exit(main())
