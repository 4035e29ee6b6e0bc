"""
The node's parameter services, built on the public parameter methods of rclpy's Node.

rclpy's own ParameterService (``start_parameter_services=True``) lets any peer on the DDS
domain stop the node: a ``SetParameters`` or ``SetParametersAtomically`` request whose
ParameterValue has a type outside rcl_interfaces/ParameterType (``type = 99``) raises
``ValueError`` out of the executor's spin, and the node exits with no answer sent; an empty
name slips past rclpy's check for undeclared parameters (it tests the names for truth) and
is declared.  These services answer every request: malformed ones are refused, each with
its reason, and nothing a request holds can raise out of a callback.

The six services keep rclpy's names (``<node name>/get_parameters``, ...), QoS and answers,
so ``ros2 param`` and every parameter client work unchanged:

- get_parameters, get_parameter_types, describe_parameters: all names known, or an empty
  answer (as rclpy answers a request naming an undeclared parameter);
- list_parameters: as rclpy;
- set_parameters: one result per parameter, each set on its own;
- set_parameters_atomically: all or none, one result.

A successful set's ``reason`` carries what the node's `note` says of the change (rclpy's
set_parameters_atomically drops the reason of a successful validation): an integrator switch
that waits for its kernels says so, and when it will act.
"""

from rcl_interfaces.msg import ListParametersResult
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.msg import SetParametersResult
from rcl_interfaces.srv import DescribeParameters
from rcl_interfaces.srv import GetParameters
from rcl_interfaces.srv import GetParameterTypes
from rcl_interfaces.srv import ListParameters
from rcl_interfaces.srv import SetParameters
from rcl_interfaces.srv import SetParametersAtomically
from rclpy.exceptions import ParameterException
from rclpy.exceptions import ParameterUninitializedException
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_parameters

from ..text import shortened

__all__ = ['ParameterServices', 'parameter_from_message']

_VALUE_FIELDS = {
    ParameterType.PARAMETER_BOOL: 'bool_value',
    ParameterType.PARAMETER_INTEGER: 'integer_value',
    ParameterType.PARAMETER_DOUBLE: 'double_value',
    ParameterType.PARAMETER_STRING: 'string_value',
    ParameterType.PARAMETER_BYTE_ARRAY: 'byte_array_value',
    ParameterType.PARAMETER_BOOL_ARRAY: 'bool_array_value',
    ParameterType.PARAMETER_INTEGER_ARRAY: 'integer_array_value',
    ParameterType.PARAMETER_DOUBLE_ARRAY: 'double_array_value',
    ParameterType.PARAMETER_STRING_ARRAY: 'string_array_value',
}
_TYPE_NUMBERS = ', '.join(f'{number} ({Parameter.Type(number).name.lower()})'
                          for number in sorted(_VALUE_FIELDS))


class RefusedParameter(ValueError):
    """A parameter message the node refuses; the message says why."""


def parameter_from_message(message, node):
    """
    Return the rclpy Parameter of an rcl_interfaces/Parameter message sent to `node`.

    Raises
    ------
    RefusedParameter
        For an empty name, a name `node` has not declared, or a value type that is not one
        of rcl_interfaces/ParameterType's (NOT_SET, which would undeclare it, included).

    """
    name = message.name
    if not name:
        raise RefusedParameter('a parameter name must not be empty')
    if not node.has_parameter(name):
        raise RefusedParameter(f'no parameter named {shortened(name)!r} (see '
                               '`ros2 param list`)')
    number = message.value.type
    field = _VALUE_FIELDS.get(number)
    if field is None:
        raise RefusedParameter(
            f'parameter {shortened(name)!r}: value type {number} is not a parameter type; '
            f'one of {_TYPE_NUMBERS}')
    value = getattr(message.value, field)
    if number in (ParameterType.PARAMETER_INTEGER_ARRAY, ParameterType.PARAMETER_DOUBLE_ARRAY):
        value = value.tolist()  # array.array, as the Python types rclpy checks for
    return Parameter(name, Parameter.Type(number), value)


def _refused(reason):
    return SetParametersResult(successful=False, reason=reason)


class ParameterServices:
    """
    The parameter services of `node` (created with ``start_parameter_services=False``).

    Every callback answers; see the module docstring.  `note` (optional): called with the
    parameters of a set request before they are set, returns the words ('' for none) the
    reply's ``reason`` gives if they are set.
    """

    def __init__(self, node, callback_group=None, note=None):
        self._node = node
        self._note = note
        for service_type, name, callback in (
                (DescribeParameters, 'describe_parameters', self._describe_callback),
                (GetParameters, 'get_parameters', self._get_callback),
                (GetParameterTypes, 'get_parameter_types', self._get_types_callback),
                (ListParameters, 'list_parameters', self._list_callback),
                (SetParameters, 'set_parameters', self._set_callback),
                (SetParametersAtomically, 'set_parameters_atomically',
                 self._set_atomically_callback)):
            node.create_service(service_type, f'{node.get_name()}/{name}',
                                self._answering(name, callback),
                                qos_profile=qos_profile_parameters,
                                callback_group=callback_group)

    def _answering(self, name, callback):
        """Return `callback` made to answer whatever it raises (an empty response, logged)."""
        def answer(request, response):
            try:
                return callback(request, response)
            except Exception as error:  # noqa: B902 (a peer's request must not stop the node)
                self._node.get_logger().error(
                    f'{name}: a request failed, answered empty: {shortened(repr(error))}')
                return response
        return answer

    def _declared(self, names):
        return all(name and self._node.has_parameter(name) for name in names)

    def _describe_callback(self, request, response):
        if self._declared(request.names):
            response.descriptors = self._node.describe_parameters(list(request.names))
        return response

    def _get_callback(self, request, response):
        if self._declared(request.names):
            try:
                response.values = [parameter.get_parameter_value() for parameter in
                                   self._node.get_parameters(list(request.names))]
            except ParameterUninitializedException:
                pass  # as rclpy: nothing for a request with a parameter without value
        return response

    def _get_types_callback(self, request, response):
        if self._declared(request.names):
            # (rclpy 7.1 gives the declared parameters' types as numbers, not as the
            # Parameter.Type its annotation says: either is taken.)
            response.types = [Parameter.Type(kind).value for kind in
                              self._node.get_parameter_types(list(request.names))]
        return response

    def _list_callback(self, request, response):
        try:
            response.result = self._node.list_parameters(list(request.prefixes),
                                                         int(request.depth))
        except (TypeError, ValueError):
            response.result = ListParametersResult()
        return response

    def _set_callback(self, request, response):
        response.results = [self._set([message]) for message in request.parameters]
        return response

    def _set_atomically_callback(self, request, response):
        response.result = self._set(request.parameters)
        return response

    def _set(self, messages):
        try:
            parameters = [parameter_from_message(message, self._node) for message in messages]
        except RefusedParameter as refusal:
            return _refused(str(refusal))
        # Read before the change: what it will do depends on the state it finds.
        note = self._note(parameters) if self._note is not None else ''
        try:
            result = self._node.set_parameters_atomically(parameters)
        except (ParameterException, TypeError, ValueError) as error:
            return _refused(shortened(str(error), limit=1000))
        if result.successful and note:
            result.reason = note
        return result
