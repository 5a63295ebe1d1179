"""The node's subscriptions to the robot's ROS graph, feeding a :class:`RobotWorld`.

QoS as the publishers use it (robot_state_publisher, joint_state_publisher, tf2):

* ``robot_description`` (``std_msgs/String``): reliable, transient local, depth 1, so a
  description published before the node started arrives;
* ``joint_states`` (``sensor_msgs/JointState``): best effort, depth 50, which receives from
  reliable and best-effort publishers alike; several publishers may each send some joints;
* ``/tf`` (``tf2_msgs/TFMessage``): reliable, volatile, depth 100, tf2's listener QoS;
* ``/tf_static``: reliable, transient local, depth 100.

Names are tf2's and robot_state_publisher's (``robot_description`` and ``joint_states``
relative to the node's namespace), resolved by the node's remapping rules, so the usual
remapping works.

The subscriptions belong to a node of their own (``<node>_world``, in the node's namespace),
spun by a single-threaded executor in a thread of its own. A robot publishes ``/tf`` and
``/joint_states`` at 100 Hz or more; on the node's multi-threaded executor, which waits on
every service and action of the node, each message cost about 3 ms of the node's main
thread, 60 % of a core at 200 messages a second, taken from the projections' workers. The
callbacks only take a short lock: reading the graph never waits for a query, and a query
that does not ask for the world never waits for it.
"""

from __future__ import annotations

import threading
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from projection_server.world.state import RobotWorld
from projection_server.world.transforms import Transform

__all__ = ['DESCRIPTION_QOS', 'JOINT_STATES_QOS', 'TF_QOS', 'TF_STATIC_QOS', 'WorldListener']

DESCRIPTION_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
JOINT_STATES_QOS = QoSProfile(depth=50, history=HistoryPolicy.KEEP_LAST,
                              reliability=ReliabilityPolicy.BEST_EFFORT,
                              durability=DurabilityPolicy.VOLATILE)
TF_QOS = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                    reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)
TF_STATIC_QOS = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                           reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


class WorldListener:
    """Subscribes ``node`` to the robot's description, joint states and transforms."""

    def __init__(self, node: Node):
        topic = node.resolve_topic_name   # the node's remapping rules, applied here
        # Its own node takes none of the process's rules: they would rename it as the node.
        self._node = Node(f'{node.get_name()}_world', namespace=node.get_namespace(),
                          context=node.context, use_global_arguments=False,
                          start_parameter_services=False)
        make = self._node.create_subscription
        subs = [make(String, topic('robot_description'), self._on_description,
                     DESCRIPTION_QOS),
                make(JointState, topic('joint_states'), self._on_joints, JOINT_STATES_QOS),
                make(TFMessage, topic('/tf'), self._on_tf, TF_QOS),
                make(TFMessage, topic('/tf_static'), self._on_tf_static, TF_STATIC_QOS)]
        clock = node.get_clock()
        self.world = RobotWorld(clock=lambda: clock.now().nanoseconds,
                                topics={'robot_description': subs[0].topic_name,
                                        'joint_states': subs[1].topic_name})
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(self._node)
        self._thread = threading.Thread(target=self._spin, name='world_listener',
                                        daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except ExternalShutdownException:
            pass

    def _on_description(self, msg: String) -> None:
        self.world.set_description(msg.data)

    def _on_joints(self, msg: JointState) -> None:
        stamp = _ns(msg.header.stamp) or self.world.now()   # unstamped: as received
        self.world.update_joints(msg.name, msg.position, stamp)

    def _on_tf(self, msg: TFMessage) -> None:
        self.world.add_transforms(_transforms(msg, static=False))

    def _on_tf_static(self, msg: TFMessage) -> None:
        self.world.add_transforms(_transforms(msg, static=True))

    def destroy(self) -> None:
        self._executor.shutdown()
        self._thread.join(timeout=5.0)
        self._node.destroy_node()   # and its subscriptions, which the node holds


def _transforms(msg: TFMessage, static: bool) -> list[Transform]:
    out = []
    for t in msg.transforms:
        tr, q = t.transform.translation, t.transform.rotation
        # tf2 strips a leading slash from frame ids; so do we, so that '/map' is 'map'.
        out.append(Transform(t.header.frame_id.lstrip('/'), t.child_frame_id.lstrip('/'),
                             (tr.x, tr.y, tr.z), (q.x, q.y, q.z, q.w),
                             None if static else _ns(t.header.stamp)))
    return out
