"""Decoding Foxglove protobuf messages with nothing but the schema a server or a file carries.

A schema is a serialized `google.protobuf.FileDescriptorSet` (base64 in a WebSocket
advertisement, raw bytes in an MCAP schema record); the message class is built from it with the
`protobuf` package, so these tests never use our Rust code to decode.
"""

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory


def message_class(schema_name, descriptor_set_bytes):
    """The protobuf message class `schema_name` described by `descriptor_set_bytes`."""
    files = list(descriptor_pb2.FileDescriptorSet.FromString(descriptor_set_bytes).file)
    pool = descriptor_pool.DescriptorPool()
    added = set()
    # Add files once their dependencies are in the pool (sets need not be ordered).
    while files:
        progress = False
        for file in list(files):
            if all(dependency in added for dependency in file.dependency):
                pool.Add(file)
                added.add(file.name)
                files.remove(file)
                progress = True
        if not progress:
            missing = {dep for f in files for dep in f.dependency if dep not in added}
            raise ValueError(f"{schema_name}: descriptor set lacks {sorted(missing)}")
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))


def jpeg_size(data):
    """(width, height) from a JPEG's start-of-frame segment, without decoding the image."""
    if data[:2] != b"\xff\xd8":
        raise ValueError("not a JPEG (no start-of-image marker)")
    index = 2
    while index + 4 <= len(data):
        if data[index] != 0xFF:
            raise ValueError(f"JPEG marker expected at byte {index}")
        marker = data[index + 1]
        length = int.from_bytes(data[index + 2:index + 4], "big")
        if marker in (0xC0, 0xC1, 0xC2):
            height = int.from_bytes(data[index + 5:index + 7], "big")
            width = int.from_bytes(data[index + 7:index + 9], "big")
            return width, height
        index += 2 + length
    raise ValueError("JPEG without a start-of-frame segment")


def stamp_ns(timestamp):
    """Nanoseconds of a `google.protobuf.Timestamp` (the well-known schemas' `timestamp`)."""
    return timestamp.seconds * 1_000_000_000 + timestamp.nanos
