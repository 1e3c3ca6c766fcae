"""Writes the seed corpus in seeds/: small grooms made here (curved strands over a sphere, with and without
optional arrays), and a few broken ones. Run: python3 make_seeds.py"""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def strand(index, count, points, length):
    """A strand rooted on a unit sphere's top, curving outward and down."""
    around = index * 2.399963
    height = 1.0 - 0.8 * (index + 0.5) / count
    ring = math.sqrt(1.0 - height * height)
    normal = (ring * math.cos(around), height, ring * math.sin(around))
    root = normal
    out = []
    for k in range(points):
        s = k / max(points - 1, 1)
        droop = -0.5 * length * s * s
        out.append((root[0] + normal[0] * length * s, root[1] + normal[1] * length * s + droop,
                    root[2] + normal[2] * length * s))
    return out


def tfx(strands, per_strand, thickness=False, colours=False, uvs=False):
    header_words = 40  # 160 bytes
    body = b""
    offset = 160
    positions = offset
    for i in range(strands):
        for p in strand(i, strands, per_strand, 3.0):
            body += struct.pack("<4f", *p, 0.0)
    offsets = [positions, 0, 0, 0, 0]
    if uvs:
        offsets[1] = 160 + len(body)
        body += b"".join(struct.pack("<2f", i / strands, 0.5) for i in range(strands))
        offsets[2] = 160 + len(body)
        body += b"".join(struct.pack("<2f", 0.1, 0.2) for _ in range(strands * per_strand))
    if thickness:
        offsets[3] = 160 + len(body)
        body += b"".join(struct.pack("<f", 0.5 + i) for i in range(strands))
    if colours:
        offsets[4] = 160 + len(body)
        body += b"".join(struct.pack("<4f", 0.3, 0.2, 0.1, 1.0) for _ in range(strands * per_strand))
    header = struct.pack("<fII5I", 4.0, strands, per_strand, *offsets)
    header += b"\0" * (160 - len(header))
    return header + body


def hair(segments, arrays, default_segments=0):
    strands = len(segments)
    points = sum(s + 1 for s in segments)
    header = b"HAIR" + struct.pack("<III", strands, points, arrays)
    header += struct.pack("<Iff3f", default_segments, 0.01, 0.0, 0.4, 0.3, 0.2)
    header += b"made by make_seeds.py".ljust(88, b"\0")
    body = b""
    if arrays & 1:
        body += b"".join(struct.pack("<H", s) for s in segments)
    for i, s in enumerate(segments):
        for p in strand(i, strands, s + 1, 2.0):
            body += struct.pack("<3f", *p)
    if arrays & 4:
        body += b"".join(struct.pack("<f", 0.008) for _ in range(points))
    if arrays & 8:
        body += b"".join(struct.pack("<f", 0.1) for _ in range(points))
    if arrays & 16:
        body += b"".join(struct.pack("<3f", 0.5, 0.4, 0.3) for _ in range(points))
    return header + body


seeds = {
    "tfx/plain": tfx(4, 8),
    "tfx/every_array": tfx(3, 6, thickness=True, colours=True, uvs=True),
    "tfx/two_points": tfx(2, 2),
    "tfx/truncated": tfx(4, 8)[:200],
    "hair/segments_points": hair([5, 7, 3], 1 | 2),
    "hair/every_array": hair([4, 4], 1 | 2 | 4 | 8 | 16),
    "hair/default_segments": hair([6, 6, 6], 2, default_segments=6),
    "hair/one_point_strands": hair([0, 0, 2], 1 | 2),
    "hair/truncated": hair([5, 7, 3], 1 | 2)[:150],
}
for name, data in seeds.items():
    path = os.path.join(HERE, "seeds", name)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "wb") as file:
        file.write(data)
print(f"{len(seeds)} seeds written")
