#!/usr/bin/env python3
"""Writes an ASCII RIB file in RIB's binary encoding (RI Spec 3.2, appendix C),
as a RIB writer's binary mode would: each request defined once (0314) and sent
by code (0246), strings as defined tokens (0315/0317) while there are codes
left, integers as two-byte fixed point (0201), other numbers as floats (0244),
arrays of numbers as counted float arrays (0310 + n). For testing the reader
(a binary form of the geometry fuzz seed found a subdivision input that
never finishes: see the session note).

    scripts/rib_to_binary.py in.rib out.rib
"""
import re
import struct
import sys


def encoded_string(s):
    b = s.encode()
    if len(b) < 16:
        return bytes([0o220 + len(b)]) + b
    return bytes([0o241]) + struct.pack('>H', len(b)) + b


def main(source, target):
    text = open(source).read()
    tokens = re.findall(r'"(?:[^"\\]|\\.)*"|\[|\]|#[^\n]*|[^\s\[\]"#]+', text)
    out, requests, strings, array = bytearray(), {}, {}, None

    def string(s):
        if s not in strings and len(strings) < 256:
            strings[s] = len(strings)
            return bytes([0o315, strings[s]]) + encoded_string(s) + bytes([0o317, strings[s]])
        return bytes([0o317, strings[s]]) if s in strings else encoded_string(s)

    for t in tokens:
        if t.startswith('#'):
            continue
        if t == '[':
            array = []
        elif t == ']':
            if array and all(isinstance(x, float) for x in array):
                out += bytes([0o311]) + struct.pack('>H', len(array)) + b''.join(struct.pack('>f', x) for x in array)
            else:
                out += b'[' + b''.join(x if isinstance(x, bytes) else struct.pack('>Bf', 0o244, x) for x in array) + b']'
            array = None
        elif t.startswith('"'):
            e = string(t[1:-1])
            if array is not None:
                array.append(e)
            else:
                out += e
        else:
            try:
                v = float(t)
            except ValueError:
                if t not in requests:
                    requests[t] = len(requests)
                    out += bytes([0o314, requests[t]]) + encoded_string(t)
                out += bytes([0o246, requests[t]])
                continue
            if array is not None:
                array.append(v)
            elif re.fullmatch(r'[+-]?\d+', t) and -32768 <= int(t) < 32768:
                out += bytes([0o201]) + struct.pack('>h', int(t))
            else:
                out += bytes([0o244]) + struct.pack('>f', v)
    open(target, 'wb').write(bytes(out))


if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2])
