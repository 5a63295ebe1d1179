"""The paper's results (Kunze, Dolha & Beetz, IROS 2011, section IV) as data.

Keys are tuples of parameter values in the order of the experiment's parameters
(first parameter slowest, as ``make_projection/4`` enumerates them).
"""

from __future__ import annotations

__all__ = [
    'TABLE_I',
    'TABLE_II',
    'TABLE_II_COLUMNS',
    'TABLE_III',
    'GRASP_FORCES',
    'GRASP_POSITIONS',
    'POUR_ANGLES',
    'POUR_POSITIONS',
    'POUR_TIMES',
    'TURN_ANGLES',
]

# Table I: qualitative results of grasping an egg, keyed (force [N], position [m]).
GRASP_FORCES = (1, 3, 5, 7, 9, 11)
GRASP_POSITIONS = (-0.02, 0.00, 0.02)
_TABLE_I_ROWS = {
    -0.02: ('slip', 'ok', 'slip', 'ok', 'break', 'break'),
    0.00: ('slip', 'ok', 'ok', 'ok', 'ok', 'break'),
    0.02: ('slip', 'ok', 'ok', 'ok', 'break', 'break'),
}
TABLE_I = {(force, position): row[i]
           for position, row in _TABLE_I_ROWS.items()
           for i, force in enumerate(GRASP_FORCES)}

# Table II: pouring a pancake mix, keyed (position [m], time [s], angle [rad]).
# Values: particles on the pan, particles spilled, centroid offset x and y [m],
# roundness; None is the paper's "—" (undefined: too few particles on the pan).
POUR_POSITIONS = (-0.09, 0.00, 0.07)
POUR_TIMES = (0.0, 0.5, 1.0)
POUR_ANGLES = (1.84, 1.99, 2.14)
TABLE_II_COLUMNS = ('pan', 'spill', 'off_x', 'off_y', 'round')
_TABLE_II_ROWS = [
    # pos, time, angle, pan, spill, off_x, off_y, round
    (-0.09, 0.0, 1.84, 2, 0, -0.004, -0.098, 0.00),
    (-0.09, 0.0, 1.99, 25, 2, -0.028, -0.096, 0.19),
    (-0.09, 0.0, 2.14, 106, 6, -0.011, -0.095, 0.55),
    (-0.09, 0.5, 1.84, 14, 1, -0.021, -0.094, 0.14),
    (-0.09, 0.5, 1.99, 95, 6, -0.005, -0.087, 0.89),
    (-0.09, 0.5, 2.14, 205, 16, 0.005, -0.086, 0.51),
    (-0.09, 1.0, 1.84, 57, 1, -0.007, -0.091, 0.37),
    (-0.09, 1.0, 1.99, 163, 6, 0.000, -0.083, 0.58),
    (-0.09, 1.0, 2.14, 247, 28, 0.000, -0.085, 0.59),
    (0.00, 0.0, 1.84, 1, 0, 0.008, -0.110, None),
    (0.00, 0.0, 1.99, 41, 0, -0.025, -0.004, 0.51),
    (0.00, 0.0, 2.14, 100, 1, -0.015, -0.003, 0.77),
    (0.00, 0.5, 1.84, 19, 0, -0.010, -0.005, 0.19),
    (0.00, 0.5, 1.99, 81, 0, -0.022, -0.004, 0.57),
    (0.00, 0.5, 2.14, 212, 0, -0.009, -0.003, 0.89),
    (0.00, 1.0, 1.84, 36, 1, -0.016, 0.000, 0.57),
    (0.00, 1.0, 1.99, 132, 0, -0.015, 0.001, 0.57),
    (0.00, 1.0, 2.14, 255, 2, -0.019, 0.000, 0.88),
    (0.07, 0.0, 1.84, 0, 0, None, None, None),
    (0.07, 0.0, 1.99, 44, 3, -0.017, 0.067, 0.59),
    (0.07, 0.0, 2.14, 117, 1, -0.002, 0.062, 0.76),
    (0.07, 0.5, 1.84, 24, 1, -0.007, 0.054, 0.39),
    (0.07, 0.5, 1.99, 109, 2, -0.012, 0.074, 0.62),
    (0.07, 0.5, 2.14, 222, 3, -0.011, 0.062, 0.90),
    (0.07, 1.0, 1.84, 40, 0, -0.012, 0.071, 0.85),
    (0.07, 1.0, 1.99, 156, 4, -0.002, 0.068, 0.79),
    (0.07, 1.0, 2.14, 287, 5, 0.001, 0.070, 0.76),
]
TABLE_II = {row[:3]: dict(zip(TABLE_II_COLUMNS, row[3:])) for row in _TABLE_II_ROWS}

# Table III: qualitative results of turning a pancake, keyed (angle [rad],).
TURN_ANGLES = (0.1, 0.3, 0.4, 0.5, 0.7, 0.9)
TABLE_III = {(angle,): outcome for angle, outcome in
             zip(TURN_ANGLES, ('ok', 'ok', 'ok', 'fail', 'fail', 'fail'))}
