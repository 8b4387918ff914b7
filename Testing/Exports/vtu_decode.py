# SPDX-License-Identifier: GPL-3.0-or-later
"""A small independent decoder of VTK XML unstructured grids (.vtu) as VTK writes them (appended
data, base64 or raw, optionally zlib-compressed; String arrays too), used to check the .vtu export
without VTK or meshio."""
import base64
import re
import xml.etree.ElementTree as ET
import zlib

import numpy as np

_TYPES = {"Int8": "i1", "UInt8": "u1", "Int16": "i2", "UInt16": "u2", "Int32": "i4", "UInt32": "u4",
          "Int64": "i8", "UInt64": "u8", "Float32": "f4", "Float64": "f8", "String": "u1"}


def _split(raw):
    start = raw.find(b"<AppendedData")
    if start < 0:
        raise ValueError("no <AppendedData> block (FEMesher writes appended data)")
    tag_end = raw.find(b">", start)
    m = re.search(rb'encoding="(\w+)"', raw[start:tag_end])
    encoding = m.group(1).decode() if m else "raw"
    underscore = raw.find(b"_", tag_end)
    end = raw.rfind(b"</AppendedData>")
    return raw[:start], encoding, raw[underscore + 1:end]


def read_vtu(path):
    """Returns (root element of the XML header, {array name: numpy array or list of str},
    {field array name: value})."""
    raw = open(path, "rb").read()
    head, encoding, blob = _split(raw)
    root = ET.fromstring(head.decode("utf-8", "replace") + "</VTKFile>")
    order = "<" if root.get("byte_order", "LittleEndian") == "LittleEndian" else ">"
    htype = np.dtype(order + _TYPES[root.get("header_type", "UInt32")])
    compressed = root.get("compressor") is not None
    if compressed and root.get("compressor") != "vtkZLibDataCompressor":
        raise ValueError("unexpected compressor " + root.get("compressor"))
    if encoding == "base64":
        blob = blob.strip()
    arrays = [a for a in root.iter() if a.tag in ("DataArray", "Array") and a.get("format") == "appended"]
    offsets = sorted(int(a.get("offset")) for a in arrays)

    def chunk(off):
        nxt = [o for o in offsets if o > off]
        return blob[off:nxt[0] if nxt else len(blob)]

    def b64len(nbytes):
        return 4 * ((nbytes + 2) // 3)

    def decode(data):
        hs = htype.itemsize
        if not compressed:
            if encoding == "base64":
                n = int(np.frombuffer(base64.b64decode(data[:b64len(hs)])[:hs], htype)[0])
                rest = base64.b64decode(data[b64len(hs):])
                return rest[:n]
            n = int(np.frombuffer(data[:hs], htype)[0])
            return data[hs:hs + n]
        if encoding == "base64":
            nblocks = int(np.frombuffer(base64.b64decode(data[:b64len(hs)])[:hs], htype)[0])
            hlen = b64len(hs * (3 + nblocks))
            header = np.frombuffer(base64.b64decode(data[:hlen]), htype)
            body = base64.b64decode(data[hlen:])
        else:
            nblocks = int(np.frombuffer(data[:hs], htype)[0])
            header = np.frombuffer(data[:hs * (3 + nblocks)], htype)
            body = data[hs * (3 + nblocks):]
        out, pos = [], 0
        for size in header[3:3 + nblocks]:
            out.append(zlib.decompress(body[pos:pos + int(size)]))
            pos += int(size)
        return b"".join(out)

    values = {}
    for a in arrays:
        data = decode(chunk(int(a.get("offset"))))
        if a.get("type") == "String":
            strings = data.split(b"\0")
            n = int(a.get("NumberOfTuples", len(strings) - 1))
            values[a.get("Name")] = [s.decode("utf-8", "replace") for s in strings[:n]]
        else:
            arr = np.frombuffer(data, np.dtype(order + _TYPES[a.get("type")]))
            nc = int(a.get("NumberOfComponents", "1"))
            values[a.get("Name")] = arr.reshape(-1, nc) if nc > 1 else arr
    field_names = [a.get("Name") for a in root.iter("FieldData") for a in a]
    return root, values, {k: values[k] for k in field_names}

