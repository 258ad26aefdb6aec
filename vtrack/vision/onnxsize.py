"""An ONNX model's input size made free, read and written in protobuf's wire format.

A YOLOX graph is convolutions, resizes by a factor of 2 and reshapes to (1, 85, -1): it
runs on any input whose sides are multiples of 32, but its export declares one square
size, and onnxruntime refuses any other. `free_input_size` rewrites the declared height
and width of the input (and the row count of the output) as named, symbolic dimensions.

The `onnx` package would do this in three lines, but importing it takes 1-2 s of CPU
here (ml_dtypes), longer than a short clip's appearance passes; so the few fields are
edited in place. Wire format (protobuf's encoding guide): a message is a run of fields,
each a varint key (number << 3 | wire type) and a payload: a varint (type 0), 8 bytes (1),
a varint length and that many bytes (2: strings and sub-messages) or 4 bytes (5). A
TensorShapeProto.Dimension holding `dim_value` (field 1, a varint) is replaced by one of
the same length holding `dim_param` (field 2, a string), so no enclosing length changes.

The path to a dimension: ModelProto.graph (7) -> GraphProto.input (11) / output (12) ->
ValueInfoProto.type (2) -> TypeProto.tensor_type (1) -> Tensor.shape (2) ->
TensorShapeProto.dim (1); a graph input that is an initializer (GraphProto.initializer,
5; TensorProto.name, 8) is a weight, not the model's input.
"""

from __future__ import annotations

from collections.abc import Iterator

Span = tuple[int, int]   # a payload's start and end in the buffer


def _varint(buf: bytes | bytearray, pos: int) -> tuple[int, int]:
    """The varint at `pos` and the position after it."""
    value = shift = 0
    while True:
        if pos >= len(buf):
            raise ValueError("truncated protobuf varint")
        byte = buf[pos]
        value |= (byte & 0x7F) << shift
        pos += 1
        if byte < 0x80:
            return value, pos
        shift += 7


def _fields(buf: bytes | bytearray, span: Span) -> Iterator[tuple[int, int, Span]]:
    """The fields of the message in buf[span]: (number, wire type, payload span)."""
    pos, end = span
    while pos < end:
        key, pos = _varint(buf, pos)
        wire = key & 7
        if wire == 0:
            start, (_, pos) = pos, _varint(buf, pos)
        elif wire == 2:
            length, start = _varint(buf, pos)
            pos = start + length
        elif wire in (1, 5):
            start, pos = pos, pos + (8 if wire == 1 else 4)
        else:
            raise ValueError(f"protobuf wire type {wire} is not read here")
        if pos > end:
            raise ValueError("truncated protobuf field")
        yield key >> 3, wire, (start, pos)


def _messages(buf: bytes | bytearray, span: Span, number: int) -> list[Span]:
    """The payload spans of the length-delimited fields `number` of the message in span."""
    return [s for n, wire, s in _fields(buf, span) if n == number and wire == 2]


def _one(buf: bytes | bytearray, span: Span, path: tuple[int, ...]) -> Span:
    """The sub-message reached from span along the field numbers `path` (first of each)."""
    for number in path:
        found = _messages(buf, span, number)
        if not found:
            raise ValueError(f"protobuf field {number} missing")
        span = found[0]
    return span


def _dims(buf: bytes | bytearray, value_info: Span) -> list[Span]:
    """The Dimension messages of a ValueInfoProto's tensor shape."""
    return _messages(buf, _one(buf, value_info, (2, 1, 2)), 1)


def _dim_value(buf: bytes | bytearray, dim: Span) -> int | None:
    """A Dimension's dim_value, None where it is symbolic or unknown."""
    for number, wire, (start, _) in _fields(buf, dim):
        if number == 1 and wire == 0:
            return _varint(buf, start)[0]
    return None


def _make_symbolic(buf: bytearray, dim: Span, letter: bytes) -> None:
    """Overwrite a Dimension (3..129 bytes) with a dim_param of the same length, `letter`
    repeated (dimensions of one name must be equal)."""
    start, end = dim
    size = end - start - 2
    buf[start:end] = bytes([0x12, size]) + letter * size


def free_input_size(data: bytes) -> tuple[bytes, tuple[int, ...]]:
    """The serialised ONNX model `data` with the height and width of its one input and the
    second dimension of its one output made symbolic; and the input's declared shape.
    Raises ValueError for a model without one input and one output of known rank."""
    buf = bytearray(data)
    graph = _one(buf, (0, len(buf)), (7,))
    weights = {bytes(buf[slice(*_one(buf, t, (8,)))]) for t in _messages(buf, graph, 5)
               if _messages(buf, t, 8)}
    inputs = [v for v in _messages(buf, graph, 11)
              if not _messages(buf, v, 1) or bytes(buf[slice(*_one(buf, v, (1,)))])
              not in weights]
    outputs = _messages(buf, graph, 12)
    if len(inputs) != 1 or len(outputs) != 1:
        raise ValueError("not one input and one output")
    dims = _dims(buf, inputs[0])
    shape = tuple(_dim_value(buf, d) or 0 for d in dims)
    out_dims = _dims(buf, outputs[0])
    if len(dims) != 4 or len(out_dims) != 3:
        raise ValueError(f"input of rank {len(dims)}, output of rank {len(out_dims)}: "
                         f"not an image detector's")
    for dim, letter in ((dims[2], b"h"), (dims[3], b"w"), (out_dims[1], b"n")):
        if not 3 <= dim[1] - dim[0] <= 129:   # a one-letter name at least
            raise ValueError("a dimension of unexpected size")
        _make_symbolic(buf, dim, letter)
    return bytes(buf), shape
