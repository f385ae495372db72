"""Decodes every message of a harvest recording with nothing but the schema text the file carries.

An independent reader of the schemas the recorder stores (record_and_read.rs runs it): it parses
the `layout:` part of each `harvest message schema` (Rust-like notation, see
harvest_ipc::schema) and decodes the bytes by it, with the official `mcap` reader and Python's
`struct`. Prints one JSON document: per message its topic, its size, the bytes the schema
accounted for and the decoded value (arrays of more than 4096 fixed-width items as
{"items": n, "bytes": b}, as harvest_ipc::schema::decode_json shows them).
"""

import json
import math
import re
import struct
import sys

from mcap.reader import make_reader

NUMBERS = {"u8": "<B", "u16": "<H", "u32": "<I", "u64": "<Q", "i8": "<b", "i16": "<h",
           "i32": "<i", "i64": "<q", "f32": "<f", "f64": "<d"}
EXPANDED_ITEMS = 4096


def parse_schema(text):
    """The definitions of a schema text: name -> ("struct", [(field, type)]) or ("enum", {})."""
    lines = text.split("\n")
    start = lines.index("layout:") + 1
    definitions, message, current = {}, None, None
    for line in lines[start:]:
        layout = line.split(" # ")[0].rstrip()
        if not layout:
            continue
        head = re.fullmatch(r"(message|struct) (\w+) \{", layout)
        enum = re.fullmatch(r"enum (\w+): u8 \{", layout)
        if head:
            current = head.group(2)
            definitions[current] = ("struct", [])
            message = message or current
        elif enum:
            current = enum.group(1)
            definitions[current] = ("enum", {})
        elif layout == "}":
            current = None
        elif definitions[current][0] == "struct":
            name, ty = re.fullmatch(r"  (\w+): (.+)", layout).groups()
            definitions[current][1].append((name, parse_type(ty)))
        else:
            code, name = re.fullmatch(r"  (\d+) = (\w+)", layout).groups()
            definitions[current][1][int(code)] = name
    return message, definitions


def parse_type(ty):
    """A type expression as a tuple: ("number", fmt), ("array", item, n), ("sequence", item,
    max), ("counted", item, field, max), ("text", max) or ("named", name)."""
    if ty in NUMBERS:
        return ("number", NUMBERS[ty])
    text = re.fullmatch(r"string <= (\d+) bytes", ty)
    if text:
        return ("text", int(text.group(1)))
    if ty.startswith("[") and ty.endswith("]"):
        inner, _, length = ty[1:-1].rpartition("; ")
        item = parse_type(inner)
        if length.isdigit():
            return ("array", item, int(length))
        sequence = re.fullmatch(r"u64 count <= (\d+)", length)
        if sequence:
            return ("sequence", item, int(sequence.group(1)))
        field, maximum = re.fullmatch(r"([\w.]+) <= (\d+)", length).groups()
        return ("counted", item, field, int(maximum))
    return ("named", ty)


class Decoder:
    def __init__(self, definitions, data):
        self.definitions, self.data, self.at, self.numbers = definitions, data, 0, {}

    def take(self, n, path):
        if self.at + n > len(self.data):
            raise ValueError(f"{path}: {n} bytes needed, {len(self.data) - self.at} left")
        chunk = self.data[self.at:self.at + n]
        self.at += n
        return chunk

    def width(self, ty):
        """Bytes of every value of `ty` when fixed, else None."""
        kind = ty[0]
        if kind == "number":
            return struct.calcsize(ty[1])
        if kind == "array":
            item = self.width(ty[1])
            return None if item is None else item * ty[2]
        if kind == "named":
            definition = self.definitions[ty[1]]
            if definition[0] == "enum":
                return 1
            widths = [self.width(field_ty) for _, field_ty in definition[1]]
            return None if None in widths else sum(widths)
        return None

    def items(self, item, count, path):
        width = self.width(item)
        if width is not None and count > EXPANDED_ITEMS:
            self.take(width * count, path)
            return {"items": count, "bytes": width * count}
        return [self.value(item, f"{path}[{i}]") for i in range(count)]

    def value(self, ty, path):
        kind = ty[0]
        if kind == "number":
            (value,) = struct.unpack(ty[1], self.take(struct.calcsize(ty[1]), path))
            if ty[1][1] in "BHIQ":
                self.numbers[path] = value
            if isinstance(value, float) and not math.isfinite(value):
                return None  # as the JSON views show NaN and infinities
            return value
        if kind == "array":
            return self.items(ty[1], ty[2], path)
        if kind == "sequence":
            (count,) = struct.unpack("<Q", self.take(8, path))
            if count > ty[2]:
                raise ValueError(f"{path}: count {count} over {ty[2]}")
            return self.items(ty[1], count, path)
        if kind == "counted":
            count = self.numbers[ty[2]]
            if count > ty[3]:
                raise ValueError(f"{path}: count {count} over {ty[3]}")
            return self.items(ty[1], count, path)
        if kind == "text":
            (count,) = struct.unpack("<Q", self.take(8, path))
            if count > ty[1]:
                raise ValueError(f"{path}: {count} bytes over {ty[1]}")
            return self.take(count, path).decode("utf-8")
        definition = self.definitions[ty[1]]
        if definition[0] == "enum":
            return self.take(1, path)[0]
        out = {}
        for name, field_ty in definition[1]:
            out[name] = self.value(field_ty, f"{path}.{name}" if path else name)
        return out


def main(path):
    out = {"messages": []}
    parsed = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if schema is None or not schema.data.startswith(b"harvest message schema\n"):
                continue
            if schema.id not in parsed:
                parsed[schema.id] = parse_schema(schema.data.decode("utf-8"))
            name, definitions = parsed[schema.id]
            decoder = Decoder(definitions, message.data)
            value = decoder.value(("named", name), "")
            out["messages"].append({"topic": channel.topic, "size": len(message.data),
                                    "used": decoder.at, "value": value})
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1])
