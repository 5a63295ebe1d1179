"""Projection logs as rosbag2 bags (MCAP), written and read with rosbags.

The parts: :mod:`.schema` (topics, QoS, message types, the records messages stand for),
:mod:`.cdr` (serializing a sample's messages from templates), :mod:`.writer` (one bag),
:mod:`.mcap` (rosbags' writer made faster: the one module that touches rosbags'
internals, pinned to a version), :mod:`.reader` (messages and records of a bag).

One bag per projection. Standard message types where they fit (``tf2_msgs/TFMessage``,
``visualization_msgs/MarkerArray``), the project's ``projection_interfaces`` messages for
the monitored state. Timestamps are integer nanoseconds of simulated time from the start of
the projection.

Topics (:data:`TOPICS`):

========================  ===================================================================
``/projection/info``      ``ProjectionInfo``, once at t = 0: scenario, program, parameters,
                          settings, code version
``/tf_static``            ``TFMessage``, once: poses of static bodies (table, floor...)
``/tf``                   ``TFMessage``, every monitoring step: poses of the other bodies
                          (parent frame ``world``) and of their links: a robot's links as a
                          chain under the robot (each in its URDF parent link's frame), other
                          bodies' links in ``world``
``/clock``                ``rosgraph_msgs/Clock``, every monitoring step: the simulated time
``/projection/markers``   ``MarkerArray``: shapes of the bodies, at t = 0 and on each change
``/projection/contacts``  ``ContactArray``, every monitoring step
``/projection/gripper``   ``GripperState``, every monitoring step, one per gripper
``/projection/objects``   ``ObjectStateArray``, every monitoring step (loads, broken flags)
``/projection/task``      ``TaskState``, every monitoring step, one per robot, of tasks that
                          report their state: the plan step (or program phase) under way
                          and its target
``/projection/batter``    ``std_msgs/Float64MultiArray``, every monitoring step, one per fluid
                          whose heat is simulated: ``layout.dim[0].label`` the fluid, its
                          ``size`` 2; ``dim[1]`` the particles; ``data`` their temperatures
                          [deg C], then their set flags (1.0 set, 0.0 not)
``/projection/bonds``     ``std_msgs/UInt32MultiArray``, at the first monitoring step and
                          whenever they change, one per such fluid: the bonds in force as
                          particle index pairs (``dim[0].label`` the fluid, ``size`` the
                          number of bonds; ``dim[1]`` of size 2), flattened
``/robot_description``    ``std_msgs/String``, once at t = 0: the URDF of the first robot
                          whose model has one, its links renamed to their ``/tf`` frames
                          (the root link is the robot's frame, link L is ``<robot>/L``); every
                          other robot R's on ``/R/robot_description``
========================  ===================================================================

Each topic records the QoS its publisher would offer (:func:`offered_qos`), as rosbag2
does, so that ``ros2 bag play`` republishes ``/tf_static`` and the robot descriptions
transient-local (a late RViz still gets the static frames and draws the robot) and
everything reliable.

Messages written every monitoring step have a layout that does not change from one sample
to the next (the same frames, the same contact pairs, the same particles): a
:class:`CdrTemplate` made once from a prototype message serializes them by writing the
numbers into the prototype's CDR bytes, with the bytes rosbags' ``serialize_cdr`` gives.
What does not depend on the messages (message definitions and hashes, each topic's QoS as
YAML, the layout of ``metadata.yaml``) is computed once per process.
"""

from __future__ import annotations

from projection_server.bags.cdr import CdrTemplate
from projection_server.bags.reader import read_bag, read_records, records_of
from projection_server.bags.schema import (INTERFACE_PACKAGE, is_latched, LATCHED,
                                           message_definitions, offered_qos, PARTICLES_NS,
                                           Record, REFERENCE_LINKS, robot_description_topic,
                                           TfBlock, TOPICS, typestore)
from projection_server.bags.writer import BagWriter

__all__ = [
    'BagWriter',
    'CdrTemplate',
    'INTERFACE_PACKAGE',
    'LATCHED',
    'PARTICLES_NS',
    'REFERENCE_LINKS',
    'Record',
    'TOPICS',
    'TfBlock',
    'is_latched',
    'message_definitions',
    'offered_qos',
    'read_bag',
    'read_records',
    'records_of',
    'robot_description_topic',
    'typestore',
]
