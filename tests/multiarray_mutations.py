"""Mutations of a valid ``Float64MultiArray`` (one fault each), shared by the message rejection tests."""

from collections.abc import Callable

from std_msgs.msg import Float64MultiArray, MultiArrayDimension

Mutation = Callable[[Float64MultiArray], None]


def set_dim(
    index: int, label: str | None = None, size: int | None = None, stride: int | None = None
) -> Mutation:
    def mutate(msg: Float64MultiArray) -> None:
        dim = msg.layout.dim[index]
        if label is not None:
            dim.label = label
        if size is not None:
            dim.size = size
        if stride is not None:
            dim.stride = stride

    return mutate


def set_offset(msg: Float64MultiArray) -> None:
    msg.layout.data_offset = 1


def drop_stamp(msg: Float64MultiArray) -> None:
    msg.layout.dim = list(msg.layout.dim)[:-1]


def stamp_first(msg: Float64MultiArray) -> None:
    dims_list = list(msg.layout.dim)
    msg.layout.dim = [dims_list[-1], *dims_list[:-1]]


def extra_dim(msg: Float64MultiArray) -> None:
    msg.layout.dim = [*msg.layout.dim, MultiArrayDimension(label="extra:x", size=1, stride=1)]


def second_stamp(msg: Float64MultiArray) -> None:
    msg.layout.dim = [*msg.layout.dim, MultiArrayDimension(label="stamp_ns:1", size=1, stride=1)]


def set_data(values: list[float]) -> Mutation:
    def mutate(msg: Float64MultiArray) -> None:
        msg.data = values

    return mutate
