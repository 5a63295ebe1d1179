"""A robot's ROS graph for tests: a real rclpy node in the test process that publishes a
Panda's description, joint states and transforms, as robot_state_publisher, a joint state
publisher and perception would."""

from __future__ import annotations

from pathlib import Path
import re
import threading

import pybullet_data
from rclpy.executors import SingleThreadedExecutor
from geometry_msgs.msg import TransformStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from projection_server.world.listener import DESCRIPTION_QOS, TF_QOS, TF_STATIC_QOS

PANDA_URDF = Path(pybullet_data.getDataPath()) / 'franka_panda' / 'panda.urdf'
# A configuration that is not the knowledge base's home (0 -0.785 0 -2.356 0 1.571 0.785).
JOINTS = {'panda_joint1': 0.3, 'panda_joint2': -0.4, 'panda_joint3': 0.2,
          'panda_joint4': -2.0, 'panda_joint5': 0.1, 'panda_joint6': 1.9,
          'panda_joint7': 0.5, 'panda_finger_joint1': 0.03}
BASE = ((-0.68, 0.0, 0.72), (0.0, 0.0, 0.0, 1.0))


def panda_description() -> str:
    """The Panda's URDF as a ROS robot publishes it: meshes named by package:// URIs of the
    package that has them (pybullet_data's franka_panda/)."""
    text = PANDA_URDF.read_text()
    return re.sub(r'package://meshes/', 'package://franka_panda/meshes/', text)


class RobotGraph:
    """Publishes ``description`` (transient local), ``joints`` on joint_states and the
    ``frames`` (child -> (parent, xyz, quaternion, age s)) on /tf at ``rate`` Hz, the base
    on /tf_static; attributes may be changed while it runs."""

    def __init__(self, node, prefix: str = '', rate: float = 50.0):
        self.node = node
        self.description = panda_description()
        self.joints = dict(JOINTS)
        self.frames: dict[str, tuple[str, tuple, tuple, float]] = {}
        self._description_pub = node.create_publisher(String, f'{prefix}robot_description',
                                                      DESCRIPTION_QOS)
        self._joints_pub = node.create_publisher(JointState, f'{prefix}joint_states', 10)
        self._tf_pub = node.create_publisher(TFMessage, f'{prefix}tf', TF_QOS)
        self._static_pub = node.create_publisher(TFMessage, f'{prefix}tf_static',
                                                 TF_STATIC_QOS)
        self.publish_description()
        self._static_pub.publish(TFMessage(transforms=[
            self._transform('map', 'panda_link0', *BASE, 0.0)]))
        self._timer = node.create_timer(1.0 / rate, self._tick)
        self._executor = SingleThreadedExecutor()
        self._executor.add_node(node)
        self._thread = threading.Thread(target=self._executor.spin, daemon=True)
        self._thread.start()

    def publish_description(self, text: str | None = None) -> None:
        if text is not None:
            self.description = text
        self._description_pub.publish(String(data=self.description))

    def _transform(self, parent, child, xyz, q, age) -> TransformStamped:
        t = TransformStamped()
        stamp = self.node.get_clock().now().nanoseconds - int(age * 1e9)
        t.header.stamp.sec, t.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
        t.header.frame_id, t.child_frame_id = parent, child
        t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = xyz
        (t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
         t.transform.rotation.w) = q
        return t

    def _tick(self) -> None:
        msg = JointState(name=list(self.joints), position=[float(v) for v in
                                                           self.joints.values()])
        msg.header.stamp = self.node.get_clock().now().to_msg()
        self._joints_pub.publish(msg)
        frames = dict(self.frames)
        if frames:
            self._tf_pub.publish(TFMessage(transforms=[
                self._transform(parent, child, xyz, q, age)
                for child, (parent, xyz, q, age) in frames.items()]))

    def close(self) -> None:
        self._executor.shutdown()
        self._thread.join(timeout=5.0)
        self.node.destroy_timer(self._timer)
