"""``gripper``: a robot's gripper, given as a part of the robot (the robot's ``gripper``
names it) and built by the robot's model. Its friction is the pads' rubber; ``urdf`` names
the asset (``robots/assets/<stem>.urdf`` + ``.yaml``)."""

from __future__ import annotations

from projection_server.simulation.objects.registry import (FRACTION, NAME, NONNEGATIVE,
                                                           ObjectClass, POSITIVE, Property,
                                                           register)

__all__ = ['GRIPPER']

GRIPPER = register(ObjectClass(
    name='gripper',
    properties=(Property('urdf', 'pr2_gripper.urdf', NAME),
                Property('friction', 0.8, NONNEGATIVE),
                Property('restitution', 0.0, FRACTION),
                Property('max_force', 80.0, POSITIVE, 'N',
                         'the grip force a program commands is capped at this'),
                Property('max_opening', 0.09, POSITIVE, 'm',
                         "the fingers' travel ends here")),
    fixed={'shape': 'urdf'},
    build=None,
    doc=' '.join(__doc__.split('\n\n')[0].split()),
))
