"""Writes Mannequin.glb beside this file: a skinned, animated humanoid made for this crate (CC0, see
Mannequin.LICENSE.md), the glTF character its examples and tests put hair on.

It is made as the characters games buy are: modelled in centimetres (spawn it at a scale of 0.01), standing
+Y up and facing +Z (glTF's convention), its joints with axes of their own (the head joint's +X looks
down the face, as in Bevy's fox), a jaw joint under the head, and its skin in named meshes: `Face` (the
head with its jaw, nose and ears), `Eyes`, `Scalp` (the skin hair grows on, its edge a hairline),
`Body`. Its clips are Idle (0), Walk (1) and LookAround (2), each looping.

The body is a wooden artist's mannequin: each limb an ellipsoid carried rigidly by its joint, the neck
bending between the neck and head joints. Run: python3 make_mannequin.py (standard library only).
"""
import json
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))

# ---------------------------------------------------------------------------------------------------------
# Small vector and quaternion helpers (quaternions as x, y, z, w, glTF's order).


def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def scale(a, s):
    return tuple(x * s for x in a)


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def normalize(a):
    length = math.sqrt(dot(a, a))
    return scale(a, 1.0 / length)


def quat_axis_angle(axis, angle):
    axis = normalize(axis)
    s = math.sin(angle / 2.0)
    return (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2.0))


IDENTITY = (0.0, 0.0, 0.0, 1.0)


def quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def quat_conj(q):
    return (-q[0], -q[1], -q[2], q[3])


def rotate(q, v):
    p = quat_mul(quat_mul(q, (v[0], v[1], v[2], 0.0)), quat_conj(q))
    return p[:3]


def matrix(rotation, translation):
    """Column-major 4x4 of a rotation then a translation (glTF's layout)."""
    columns = [rotate(rotation, axis) for axis in ((1, 0, 0), (0, 1, 0), (0, 0, 1))]
    m = []
    for column in columns:
        m.extend([column[0], column[1], column[2], 0.0])
    m.extend([translation[0], translation[1], translation[2], 1.0])
    return m


def inverse_matrix(rotation, translation):
    inverse = quat_conj(rotation)
    return matrix(inverse, scale(rotate(inverse, translation), -1.0))


def srgb_to_linear(c):
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


# ---------------------------------------------------------------------------------------------------------
# The skeleton, in the bind pose: each joint's place in the model (cm) and its rotation there.

# Name, parent, place (cm), rotation in the model. The head joint's +X looks down the face (+Z) and its +Y
# up through the crown: a rig's own axes, not the model's.
HEAD_ROTATION = quat_axis_angle((0, 1, 0), -math.pi / 2.0)
JOINTS = [
    ("Hips", None, (0.0, 96.0, 0.0), IDENTITY),
    ("Spine", "Hips", (0.0, 108.0, 0.0), IDENTITY),
    ("Chest", "Spine", (0.0, 124.0, 0.0), IDENTITY),
    ("Neck", "Chest", (0.0, 145.0, -1.0), IDENTITY),
    ("Head", "Neck", (0.0, 155.0, 0.0), HEAD_ROTATION),
    ("Jaw", "Head", (0.0, 160.0, 2.0), HEAD_ROTATION),
    ("UpperArm.L", "Chest", (19.0, 141.0, -1.0), IDENTITY),
    ("ForeArm.L", "UpperArm.L", (21.0, 114.0, -1.0), IDENTITY),
    ("UpperArm.R", "Chest", (-19.0, 141.0, -1.0), IDENTITY),
    ("ForeArm.R", "UpperArm.R", (-21.0, 114.0, -1.0), IDENTITY),
    ("Thigh.L", "Hips", (9.5, 92.0, 0.0), IDENTITY),
    ("Shin.L", "Thigh.L", (9.5, 50.0, 0.0), IDENTITY),
    ("Thigh.R", "Hips", (-9.5, 92.0, 0.0), IDENTITY),
    ("Shin.R", "Thigh.R", (-9.5, 50.0, 0.0), IDENTITY),
]
JOINT_INDEX = {name: index for index, (name, _, _, _) in enumerate(JOINTS)}
BIND = {name: (place, rotation) for name, _, place, rotation in JOINTS}


def local_bind(name):
    """A joint's translation and rotation in its parent's space at the bind pose."""
    _, parent, place, rotation = JOINTS[JOINT_INDEX[name]]
    if parent is None:
        return place, rotation
    parent_place, parent_rotation = BIND[parent]
    inverse = quat_conj(parent_rotation)
    return rotate(inverse, sub(place, parent_place)), quat_mul(inverse, rotation)


# The skull: an ellipsoid about this point (cm), 15 cm across, 18.4 cm tall, 19.4 cm deep.
SKULL_CENTRE = (0.0, 165.5, 0.0)
SKULL = (7.5, 9.2, 9.7)

# ---------------------------------------------------------------------------------------------------------
# Meshes: lists of (position, normal, joints, weights) vertices and triangles.


class Mesh:
    def __init__(self):
        self.positions, self.normals, self.joints, self.weights, self.triangles = [], [], [], [], []

    def vertex(self, position, normal, weights):
        """`weights`: {joint name: weight}, at most four, summing to 1."""
        pairs = sorted(weights.items(), key=lambda pair: -pair[1])[:4]
        total = sum(weight for _, weight in pairs)
        joints = [JOINT_INDEX[name] for name, _ in pairs] + [0] * (4 - len(pairs))
        weights = [weight / total for _, weight in pairs] + [0.0] * (4 - len(pairs))
        self.positions.append(position)
        self.normals.append(normalize(normal))
        self.joints.append(joints)
        self.weights.append(weights)
        return len(self.positions) - 1

    def triangle(self, a, b, c):
        """Wound anticlockwise seen from outside: flipped if it faces against its corners' normals."""
        pa, pb, pc = self.positions[a], self.positions[b], self.positions[c]
        facing = cross(sub(pb, pa), sub(pc, pa))
        outward = add(add(self.normals[a], self.normals[b]), self.normals[c])
        if dot(facing, outward) < 0.0:
            b, c = c, b
        self.triangles.append((a, b, c))


def ellipsoid(mesh, centre, semi_axes, weights, segments=32, rings=20, rotation=IDENTITY):
    """An ellipsoid of `semi_axes` (cm) turned by `rotation` about `centre`; `weights(position)` skins each
    vertex."""
    first = len(mesh.positions)
    for ring in range(rings + 1):
        polar = math.pi * ring / rings
        for segment in range(segments + 1):
            azimuth = 2.0 * math.pi * segment / segments
            unit = (math.sin(polar) * math.cos(azimuth), math.cos(polar), math.sin(polar) * math.sin(azimuth))
            local = tuple(u * s for u, s in zip(unit, semi_axes))
            normal_local = tuple(u / s for u, s in zip(unit, semi_axes))
            position = add(centre, rotate(rotation, local))
            mesh.vertex(position, rotate(rotation, normal_local), weights(position))
    for ring in range(rings):
        for segment in range(segments):
            a = first + ring * (segments + 1) + segment
            b, c, d = a + 1, a + segments + 1, a + segments + 2
            if ring > 0:
                mesh.triangle(a, b, d)
            if ring < rings - 1:
                mesh.triangle(a, d, c)


def limb(mesh, start, end, radius, joint):
    """An ellipsoid from `start` to `end` (cm) of `radius`, carried rigidly by `joint`."""
    axis = sub(end, start)
    length = math.sqrt(dot(axis, axis))
    direction = scale(axis, 1.0 / length)
    # The rotation taking +Y to the limb's direction.
    turn = cross((0.0, 1.0, 0.0), direction)
    if dot(turn, turn) < 1e-12:
        rotation = IDENTITY if direction[1] > 0 else quat_axis_angle((0, 0, 1), math.pi)
    else:
        rotation = quat_axis_angle(turn, math.acos(max(-1.0, min(1.0, direction[1]))))
    centre = scale(add(start, end), 0.5)
    ellipsoid(mesh, centre, (radius, length / 2.0 + radius * 0.35, radius), lambda _: {joint: 1.0},
              segments=20, rings=14, rotation=rotation)


def smoothstep(edge0, edge1, x):
    t = max(0.0, min(1.0, (x - edge0) / (edge1 - edge0)))
    return t * t * (3.0 - 2.0 * t)


def head_weights(position):
    """The head's skin: the head joint's, the neck's below the skull's base, the jaw's in the chin."""
    neck = (1.0 - smoothstep(150.0, 157.0, position[1])) * (1.0 - smoothstep(0.0, 5.0, position[2]))
    jaw = smoothstep(2.0, 6.0, position[2]) * (1.0 - smoothstep(157.0, 161.0, position[1])) * (1.0 - neck)
    head = max(0.0, 1.0 - neck - jaw)
    return {name: weight for name, weight in (("Head", head), ("Neck", neck), ("Jaw", jaw)) if weight > 0.0} \
        or {"Head": 1.0}


def face():
    """The head: the cranium (an ellipsoid), a jaw and chin before its lower half, a nose and two ears, each
    a closed shell of its own."""
    mesh = Mesh()

    ellipsoid(mesh, SKULL_CENTRE, SKULL, head_weights, segments=48, rings=32)
    ellipsoid(mesh, (0.0, 158.6, 2.6), (5.0, 4.8, 5.3), head_weights, segments=32, rings=20)
    ellipsoid(mesh, (0.0, 163.8, 9.4), (1.1, 2.4, 1.5), head_weights, segments=12, rings=8,
              rotation=quat_axis_angle((1, 0, 0), -0.3))
    for side in (-1.0, 1.0):
        ellipsoid(mesh, (side * 7.4, 164.5, 0.3), (1.0, 3.0, 1.9), head_weights, segments=14, rings=10)
    return mesh


def eyes():
    mesh = Mesh()
    for side in (-1.0, 1.0):
        ellipsoid(mesh, (side * 3.1, 166.8, 7.9), (1.25, 1.1, 1.25), lambda _: {"Head": 1.0}, segments=12,
                  rings=8)
    return mesh


def scalp():
    """The skin hair grows on: the skull's top, 1 mm out, down to 115 degrees from the crown at the back
    and 58 at the brow, its edge arching up to 72 over the ears (a hairline), bent by the neck at the nape."""
    mesh = Mesh()
    rings, segments = 40, 80
    semi = tuple(s + 0.1 for s in SKULL)
    for ring in range(rings + 1):
        for segment in range(segments):
            azimuth = 2.0 * math.pi * segment / segments
            facing_front = max(0.0, math.sin(azimuth)) ** 2  # the face is +Z
            below_crown = 115.0 - 57.0 * facing_front
            from_ear = math.degrees(math.acos(abs(math.cos(azimuth))))
            over_ear = 1.0 - min(1.0, max(0.0, (from_ear - 14.0) / 14.0))
            over_ear = over_ear * over_ear * (3.0 - 2.0 * over_ear)
            lowest = math.radians(below_crown + (72.0 - below_crown) * over_ear)
            polar = lowest * ring / rings
            unit = (math.sin(polar) * math.cos(azimuth), math.cos(polar), math.sin(polar) * math.sin(azimuth))
            position = add(SKULL_CENTRE, tuple(u * s for u, s in zip(unit, semi)))
            normal = tuple(u / s for u, s in zip(unit, semi))
            weights = head_weights(position)
            weights.pop("Jaw", None)
            mesh.vertex(position, normal, weights or {"Head": 1.0})
    for ring in range(rings):
        for segment in range(segments):
            a = ring * segments + segment
            b = ring * segments + (segment + 1) % segments
            c, d = a + segments, b + segments
            if ring > 0:
                mesh.triangle(a, b, d)
            mesh.triangle(a, d, c)
    return mesh


def body():
    """Neck, torso, arms and legs: a wooden mannequin's."""
    mesh = Mesh()

    def neck_weights(position):
        head = smoothstep(146.0, 156.0, position[1])
        return {"Neck": 1.0 - head, "Head": head} if head > 0.0 else {"Neck": 1.0}

    ellipsoid(mesh, (0.0, 150.0, -0.5), (5.2, 9.0, 5.2), neck_weights, segments=24, rings=14)
    ellipsoid(mesh, (0.0, 130.0, 0.0), (15.5, 15.5, 9.5), lambda _: {"Chest": 1.0}, segments=32, rings=20)
    ellipsoid(mesh, (0.0, 112.0, 0.0), (12.0, 10.0, 8.0), lambda _: {"Spine": 1.0}, segments=28, rings=16)
    ellipsoid(mesh, (0.0, 96.0, 0.0), (15.0, 10.0, 10.0), lambda _: {"Hips": 1.0}, segments=28, rings=16)
    for side, s in (("L", 1.0), ("R", -1.0)):
        ellipsoid(mesh, (s * 17.5, 140.5, -1.0), (6.0, 5.0, 6.0), lambda _, j="Chest": {j: 1.0}, segments=16,
                  rings=10)
        limb(mesh, (s * 19.0, 141.0, -1.0), (s * 21.0, 114.0, -1.0), 4.4, "UpperArm." + side)
        limb(mesh, (s * 21.0, 114.0, -1.0), (s * 22.0, 90.0, 0.5), 3.6, "ForeArm." + side)
        ellipsoid(mesh, (s * 22.3, 85.0, 1.0), (2.0, 5.0, 3.6), lambda _, j="ForeArm." + side: {j: 1.0},
                  segments=12, rings=8)
        limb(mesh, (s * 9.5, 92.0, 0.0), (s * 9.5, 50.0, 0.0), 7.0, "Thigh." + side)
        limb(mesh, (s * 9.5, 50.0, 0.0), (s * 9.5, 7.0, -1.0), 5.0, "Shin." + side)
        ellipsoid(mesh, (s * 9.5, 3.5, 4.0), (4.2, 3.5, 12.0), lambda _, j="Shin." + side: {j: 1.0},
                  segments=16, rings=10)
    return mesh


# ---------------------------------------------------------------------------------------------------------
# Clips: each joint's rotation (and the hips' place) sampled at 30 Hz over one loop, its last key its first.

def swing(axis, amplitude, frequency, phase=0.0):
    """A rotation about the model's `axis` (radians) at time t."""
    return lambda t: quat_axis_angle(axis, amplitude * math.sin(2.0 * math.pi * frequency * t + phase))


def combined(*rotations):
    def at(t):
        q = IDENTITY
        for rotation in rotations:
            q = quat_mul(q, rotation(t))
        return q
    return at


CLIPS = [
    # Standing, breathing, looking slowly left and right: the hair at rest.
    ("Idle", 4.0, {
        "Chest": swing((1, 0, 0), 0.02, 0.5),
        "Head": combined(swing((0, 1, 0), 0.25, 0.25), swing((1, 0, 0), 0.06, 0.5)),
    }, None),
    # Walking on the spot, one stride a second: the hips bob, legs and arms swing, the head steadies.
    ("Walk", 1.0, {
        "Thigh.L": swing((1, 0, 0), 0.45, 1.0),
        "Thigh.R": swing((1, 0, 0), -0.45, 1.0),
        "Shin.L": lambda t: quat_axis_angle((1, 0, 0), 0.5 * max(0.0, math.sin(2 * math.pi * t - 1.2))),
        "Shin.R": lambda t: quat_axis_angle((1, 0, 0), 0.5 * max(0.0, -math.sin(2 * math.pi * t - 1.2))),
        "UpperArm.L": swing((1, 0, 0), -0.35, 1.0),
        "UpperArm.R": swing((1, 0, 0), 0.35, 1.0),
        "ForeArm.L": lambda t: quat_axis_angle((1, 0, 0), -0.25 - 0.15 * math.sin(2 * math.pi * t)),
        "ForeArm.R": lambda t: quat_axis_angle((1, 0, 0), -0.25 + 0.15 * math.sin(2 * math.pi * t)),
        "Hips": swing((0, 1, 0), 0.1, 1.0),
        "Chest": swing((0, 1, 0), -0.14, 1.0),
        "Head": combined(swing((0, 1, 0), 0.05, 1.0), swing((0, 0, 1), 0.04, 2.0)),
    }, lambda t: (0.0, 96.0 + 2.0 * math.cos(4.0 * math.pi * t), 0.0)),
    # Looking around briskly: the head turns ±0.8 rad and nods, the neck bends: the hair swings.
    ("LookAround", 3.0, {
        "Neck": combined(swing((0, 0, 1), 0.2, 1.0 / 3.0), swing((1, 0, 0), 0.12, 2.0 / 3.0)),
        "Head": combined(swing((0, 1, 0), 0.8, 1.0 / 3.0), swing((1, 0, 0), 0.25, 2.0 / 3.0, 0.7)),
        "Chest": swing((0, 1, 0), 0.12, 1.0 / 3.0),
    }, None),
]


def local_rotation(name, delta):
    """The joint's local rotation with `delta` (a rotation about the model's axes at the joint) applied to
    its bind pose: delta is turned into the parent's space."""
    _, parent, _, rotation = JOINTS[JOINT_INDEX[name]]
    parent_rotation = BIND[parent][1] if parent else IDENTITY
    return quat_mul(quat_conj(parent_rotation), quat_mul(delta, rotation))


# ---------------------------------------------------------------------------------------------------------
# The glTF binary.

class Writer:
    def __init__(self):
        self.binary = bytearray()
        self.buffer_views, self.accessors = [], []

    def view(self, data, target=None):
        while len(self.binary) % 4:
            self.binary.append(0)
        view = {"buffer": 0, "byteOffset": len(self.binary), "byteLength": len(data)}
        if target:
            view["target"] = target
        self.binary.extend(data)
        self.buffer_views.append(view)
        return len(self.buffer_views) - 1

    def accessor(self, values, kind, component, target=None, bounds=False):
        """`values`: a list of tuples (or numbers for SCALAR)."""
        flat = [x for value in values for x in (value if isinstance(value, (tuple, list)) else (value,))]
        code, fmt = {"float": (5126, "f"), "ushort": (5123, "H"), "uint": (5125, "I")}[component]
        view = self.view(struct.pack("<%d%s" % (len(flat), fmt), *flat), target)
        accessor = {"bufferView": view, "componentType": code, "count": len(values), "type": kind}
        if bounds:
            width = len(flat) // len(values)
            accessor["min"] = [min(flat[i::width]) for i in range(width)]
            accessor["max"] = [max(flat[i::width]) for i in range(width)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def build():
    writer = Writer()
    materials = []

    def material(name, srgb, roughness):
        materials.append({"name": name, "pbrMetallicRoughness": {
            "baseColorFactor": [srgb_to_linear(c) for c in srgb] + [1.0],
            "metallicFactor": 0.0, "roughnessFactor": roughness}})
        return len(materials) - 1

    skin_tone = material("Skin", (0.78, 0.58, 0.47), 0.7)
    # The scalp is the face's skin: where the hair thins out at the hairline, no cap edge shows.
    scalp_tone = material("ScalpSkin", (0.78, 0.58, 0.47), 0.75)
    eye_tone = material("Eye", (0.08, 0.06, 0.05), 0.3)
    wood = material("Wood", (0.62, 0.5, 0.38), 0.6)

    meshes, nodes = [], []
    # Node 0: the scene's root; node 1: the armature; then the joints; then the meshes.
    nodes.append({"name": "Mannequin", "children": [1]})
    nodes.append({"name": "Armature", "children": []})
    first_joint = len(nodes)
    for name, parent, _, _ in JOINTS:
        translation, rotation = local_bind(name)
        nodes.append({"name": name, "translation": list(translation), "rotation": list(rotation)})
    for index, (name, parent, _, _) in enumerate(JOINTS):
        if parent is None:
            nodes[1]["children"].append(first_joint + index)
        else:
            nodes[first_joint + JOINT_INDEX[parent]].setdefault("children", []).append(first_joint + index)

    inverse_binds = [inverse_matrix(rotation, place) for _, _, place, rotation in JOINTS]
    skin = {"name": "MannequinSkin", "joints": [first_joint + i for i in range(len(JOINTS))],
            "skeleton": first_joint,
            "inverseBindMatrices": writer.accessor([tuple(m) for m in inverse_binds], "MAT4", "float")}

    for name, mesh, tone in (("Face", face(), skin_tone), ("Eyes", eyes(), eye_tone),
                             ("Scalp", scalp(), scalp_tone), ("Body", body(), wood)):
        component = "ushort" if len(mesh.positions) < 65536 else "uint"
        attributes = {
            "POSITION": writer.accessor(mesh.positions, "VEC3", "float", 34962, bounds=True),
            "NORMAL": writer.accessor(mesh.normals, "VEC3", "float", 34962),
            "JOINTS_0": writer.accessor([tuple(j) for j in mesh.joints], "VEC4", "ushort", 34962),
            "WEIGHTS_0": writer.accessor([tuple(w) for w in mesh.weights], "VEC4", "float", 34962),
        }
        indices = writer.accessor([i for t in mesh.triangles for i in t], "SCALAR", component, 34963)
        meshes.append({"name": name, "primitives": [{"attributes": attributes, "indices": indices,
                                                     "material": tone}]})
        nodes.append({"name": name, "mesh": len(meshes) - 1, "skin": 0})
        nodes[0]["children"].append(len(nodes) - 1)

    animations = []
    for clip, period, rotations, hips_place in CLIPS:
        keys = int(round(period * 30.0))
        times = [period * k / keys for k in range(keys + 1)]
        time_accessor = writer.accessor(times, "SCALAR", "float", bounds=True)
        samplers, channels = [], []
        for joint, delta in rotations.items():
            values = [local_rotation(joint, delta(t)) for t in times]
            # The quaternions of neighbouring keys on one side, so that the loop interpolates the short way.
            for k in range(1, len(values)):
                if dot(values[k], values[k - 1]) < 0.0:
                    values[k] = tuple(-x for x in values[k])
            samplers.append({"input": time_accessor, "output": writer.accessor(values, "VEC4", "float"),
                             "interpolation": "LINEAR"})
            channels.append({"sampler": len(samplers) - 1,
                             "target": {"node": first_joint + JOINT_INDEX[joint], "path": "rotation"}})
        if hips_place:
            values = [hips_place(t) for t in times]
            samplers.append({"input": time_accessor, "output": writer.accessor(values, "VEC3", "float"),
                             "interpolation": "LINEAR"})
            channels.append({"sampler": len(samplers) - 1,
                             "target": {"node": first_joint + JOINT_INDEX["Hips"], "path": "translation"}})
        animations.append({"name": clip, "samplers": samplers, "channels": channels})

    while len(writer.binary) % 4:
        writer.binary.append(0)
    document = {
        "asset": {"version": "2.0", "generator": "bevy_hair_sim make_mannequin.py",
                  "copyright": "CC0 1.0: bevy_hair_sim's authors"},
        "scene": 0,
        "scenes": [{"name": "Mannequin", "nodes": [0]}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "skins": [skin],
        "animations": animations,
        "buffers": [{"byteLength": len(writer.binary)}],
        "bufferViews": writer.buffer_views,
        "accessors": writer.accessors,
    }
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * ((4 - len(text) % 4) % 4)
    total = 12 + 8 + len(text) + 8 + len(writer.binary)
    out = struct.pack("<III", 0x46546C67, 2, total)
    out += struct.pack("<II", len(text), 0x4E4F534A) + text
    out += struct.pack("<II", len(writer.binary), 0x004E4942) + bytes(writer.binary)
    return out


if __name__ == "__main__":
    path = os.path.join(HERE, "Mannequin.glb")
    with open(path, "wb") as file:
        file.write(build())
    print("wrote", path)
