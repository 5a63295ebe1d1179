"""Parameter descriptors carry ranges, as `ros2 param describe` and rqt show them."""

from __future__ import annotations

from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, SetParameters


def test_numeric_parameters_describe_their_ranges(call):
    names = ['max_engines', 'default_timeout', 'max_solutions', 'idle_timeout',
             'projection_workers', 'max_bags']
    r = call(DescribeParameters, 'describe_parameters', DescribeParameters.Request(names=names))
    ranges = {d.name: (d.integer_range or d.floating_point_range) for d in r.descriptors}
    assert all(len(ranges[n]) == 1 for n in names), ranges
    assert ranges['max_solutions'][0].from_value == 1
    assert ranges['default_timeout'][0].from_value > 0


def test_a_value_outside_its_range_is_refused(call):
    value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=-1.0)
    r = call(SetParameters, 'set_parameters', SetParameters.Request(
        parameters=[Parameter(name='idle_timeout', value=value)]))
    assert not r.results[0].successful
