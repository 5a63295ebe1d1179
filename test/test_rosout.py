"""The node's logs reach /rosout, where ROS 2 tools (rqt_console, ros2 topic echo) read them."""

from __future__ import annotations

import re
import time

from projection_interfaces.srv import PrologQuery


def test_the_node_logs_each_projection_to_rosout(server, node, call):
    import rclpy
    from rcl_interfaces.msg import Log
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    name = server.strip('/')
    records: list[Log] = []
    # /rosout's publishers keep their records for late subscribers (transient local), 10 s.
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    subscription = node.create_subscription(Log, '/rosout', records.append, qos)
    try:
        query = ('make_projection(grasping, grasp_object, [(_, force, [2.7])], _)')
        r = call(PrologQuery, 'query', PrologQuery.Request(
            mode=PrologQuery.Request.ONCE, query=query, timeout=120.0), timeout=180.0)
        assert r.ok, r.message
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and not _projection_logs(records, name):
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        node.destroy_subscription(subscription)
    ended = _projection_logs(records, name)
    assert len(ended) == 1 and ended[0].level == Log.INFO
    assert re.search(r'ended in [0-9.]+ s', ended[0].msg), ended[0].msg


def _projection_logs(records, name: str) -> list:
    return [m for m in records if m.name == name
            and "grasp_object {'force': 2.7}" in m.msg and 'ended in' in m.msg]
