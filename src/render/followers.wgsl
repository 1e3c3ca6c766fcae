// Follower hairs placed and every drawn node interpolated on the GPU (see `feed.rs` for what is sent,
// `simulation/packed.rs` for the frame codes, and `followers/mod.rs` for the scheme, which `place` follows
// step by step in single precision).
//
// `frames` (once per step, one invocation per guide): the director `m1` of each of the guide's edges,
// walked from the root: the root edge's decoded from its code, each next edge's carried onto it by
// parallel transport and turned about it by the material twist of the vertex between them
// (`walk_directors` in `packed.rs` does the same on the CPU).
// `place` (once per step, one invocation per drawn node): a guide's own node is where the guide is; a
// follower node is `x_g + o_t t + o_1 m1 + o_2 m2` in the frame of the guide's edge arriving at the node,
// then, from the third node on, moved out of each collider grown by the guide's thickness.
// `draw` (every frame, one invocation per drawn node): the drawn position `a + alpha (b − a)` between the
// last two steps' placements, into the buffer the hair material reads.

struct Params {
    // Drawn nodes, guide nodes, guides, colliders.
    drawn_nodes: u32,
    guide_nodes: u32,
    guides: u32,
    colliders: u32,
    // Where the frame codes and the guide words start in `guide_data`, in words.
    frames_offset: u32,
    guides_offset: u32,
    // The fraction of the way from the step before to the last, for `draw`.
    alpha: f32,
    // Whether `place` writes every node as the step before too (1) or only those of snapping guides (0).
    snap_all: u32,
}

const DRAWN_GUIDE: u32 = 0x80000000u;
const DRAWN_PUSHED: u32 = 0x40000000u;
const DRAWN_ROOT: u32 = 0x20000000u;
const DRAWN_GUIDE_NODE: u32 = 0x1fffffffu;
const GUIDE_SNAP: u32 = 1u;
const GUIDE_NO_FRAMES: u32 = 2u;
const FROM_Y: u32 = 0x800000u;
const ANGLE_STEPS: f32 = 2097152.0;
const CODE_BITS: u32 = 0xffffffu;
// A material twist's step: a turn in 2^24 steps, rad.
const TURN_STEP: f32 = 3.7450702e-7;
const WORKGROUP: u32 = 64u;

@group(0) @binding(0) var<uniform> params: Params;
// Per drawn node: rest offset (f32 bits) and guide node | flags. Kept for the layout.
@group(0) @binding(1) var<storage, read> drawn_nodes: array<vec4<u32>>;
// Per guide node: its guide. Kept for the layout.
@group(0) @binding(2) var<storage, read> guide_of_node: array<u32>;
// This step: guide node positions (3 f32 each), frame codes (3 bytes each), per guide thickness and flags.
@group(0) @binding(3) var<storage, read> guide_data: array<u32>;
// This step's colliders: centre and bounding radius, rotation, shape.
@group(0) @binding(4) var<storage, read> colliders: array<vec4<f32>>;
// This step's placement, and the step before's (written too when a guide snaps).
@group(0) @binding(5) var<storage, read_write> placed: array<f32>;
@group(0) @binding(6) var<storage, read_write> placed_before: array<f32>;
// Per guide: its first guide node; then one past the last guide node. Kept for the layout.
@group(0) @binding(7) var<storage, read> guide_starts: array<u32>;
// This step: the director `m1` of each guide node's edge (the root edge's at the root), made by `frames`.
@group(0) @binding(8) var<storage, read_write> guide_frames: array<vec4<f32>>;

fn invocation(id: vec3<u32>, groups: vec3<u32>) -> u32 {
    return id.x + id.y * groups.x * WORKGROUP;
}

fn guide_position(node: u32) -> vec3<f32> {
    return bitcast<vec3<f32>>(vec3<u32>(guide_data[3u * node], guide_data[3u * node + 1u], guide_data[3u * node + 2u]));
}

// Bytes `3 node … 3 node + 2` of the frame codes, little-endian.
fn frame_code(node: u32) -> u32 {
    let byte = 3u * node;
    let word = params.frames_offset + byte / 4u;
    let shift = 8u * (byte % 4u);
    var code = guide_data[word] >> shift;
    if shift > 8u {
        code = code | (guide_data[word + 1u] << (32u - shift));
    }
    return code & 0xffffffu;
}

// `(sin, cos)` of the turn a material twist code stands for (`turn_sin_cos` in `packed.rs`): the quarter
// turns exactly from the code's top bits, the rest through Cephes' minimax polynomials, so that no builtin
// `sin` or `cos` is needed (WGSL allows them an absolute error of 2^-11).
fn turn_sin_cos(code: u32) -> vec2<f32> {
    let quarter = ((code + 0x200000u) >> 22u) & 3u;
    let rest = (bitcast<i32>(((code & CODE_BITS) - (quarter << 22u)) << 8u)) >> 8u;
    let r = f32(rest) * TURN_STEP;
    let r2 = r * r;
    let s = r + r * r2 * (-1.6666655e-1 + r2 * (8.332161e-3 + r2 * -1.9515296e-4));
    let c = 1.0 - 0.5 * r2 + r2 * r2 * (4.1666646e-2 + r2 * (-1.3887316e-3 + r2 * 2.4433157e-5));
    switch quarter {
        case 0u: { return vec2<f32>(s, c); }
        case 1u: { return vec2<f32>(c, -s); }
        case 2u: { return vec2<f32>(-s, -c); }
        default: { return vec2<f32>(-c, s); }
    }
}

// `v` carried from the unit tangent `a` to the unit tangent `b` (`transport` in `packed.rs`).
fn transport(a: vec3<f32>, b: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let axis = cross(a, b);
    let c = dot(a, b);
    if c <= -0.999 {
        return v;
    }
    return v * c + cross(axis, v) + axis * (dot(axis, v) / (1.0 + c));
}

// The basis direction `b1` across the unit `t` (`director_basis` in `packed.rs`).
fn basis_b1(t: vec3<f32>, from_y: bool) -> vec3<f32> {
    var axis = vec3<f32>(1.0, 0.0, 0.0);
    if from_y {
        axis = vec3<f32>(0.0, 1.0, 0.0);
    }
    return normalize(cross(t, axis));
}

// `v` made perpendicular to the unit `t` and unit (`perpendicular_unit` in `packed.rs`).
fn perpendicular_unit(v: vec3<f32>, t: vec3<f32>) -> vec3<f32> {
    let across = v - dot(v, t) * t;
    if dot(across, across) > 1e-12 {
        return normalize(across);
    }
    return basis_b1(t, abs(t.x) > abs(t.y));
}

// Glam's `Quat * Vec3`.
fn rotate(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    let b = q.xyz;
    let b2 = dot(b, b);
    return v * (q.w * q.w - b2) + b * (dot(v, b) * 2.0) + cross(b, v) * (q.w * 2.0);
}

// The director `m1` a code stands for about the unit tangent `t` (`decode_director` in `packed.rs`).
fn decode_director(t: vec3<f32>, code: u32) -> vec3<f32> {
    let b1 = basis_b1(t, (code & FROM_Y) != 0u);
    let b2 = cross(t, b1);
    let d = f32(code & (FROM_Y - 1u)) / ANGLE_STEPS;
    var cs: vec2<f32>;
    if d < 1.0 {
        cs = vec2<f32>(1.0 - d, d);
    } else if d < 2.0 {
        cs = vec2<f32>(1.0 - d, 2.0 - d);
    } else if d < 3.0 {
        cs = vec2<f32>(d - 3.0, 2.0 - d);
    } else {
        cs = vec2<f32>(d - 3.0, d - 4.0);
    }
    return normalize(cs.x * b1 + cs.y * b2);
}

// `world` moved out to the surface of collider `index` grown by `thickness` if it lies inside: radially from
// the centre (a sphere, an ellipsoid), from the axis (a capsule), straight up (a plane), from the box (a
// cuboid).
fn push_out(world: vec3<f32>, index: u32, thickness: f32) -> vec3<f32> {
    let centre = colliders[3u * index];
    let rotation = colliders[3u * index + 1u];
    let shape = colliders[3u * index + 2u];
    let offset = world - centre.xyz;
    let reach = centre.w + thickness;
    if dot(offset, offset) > reach * reach {
        return world;
    }
    let local = rotate(vec4<f32>(-rotation.xyz, rotation.w), offset);
    var outside = local;
    var inside = false;
    if shape.w == 0.0 {
        let radius = shape.x + thickness;
        if dot(local, local) < radius * radius {
            inside = true;
            if dot(local, local) > 0.0 {
                outside = normalize(local) * radius;
            } else {
                outside = vec3<f32>(0.0, radius, 0.0);
            }
        }
    } else if shape.w == 1.0 {
        let radius = shape.x + thickness;
        let axis = vec3<f32>(0.0, clamp(local.y, -shape.y, shape.y), 0.0);
        let away = local - axis;
        if dot(away, away) < radius * radius {
            inside = true;
            if dot(away, away) > 0.0 {
                outside = axis + normalize(away) * radius;
            } else {
                outside = axis + vec3<f32>(radius, 0.0, 0.0);
            }
        }
    } else if shape.w == 2.0 {
        let axes = shape.xyz + vec3<f32>(thickness);
        let scaled = length(local / axes);
        if scaled < 1.0 {
            inside = true;
            if scaled > 0.0 {
                outside = local / scaled;
            } else {
                outside = vec3<f32>(0.0, axes.y, 0.0);
            }
        }
    } else if shape.w == 3.0 {
        if local.y < 0.0 {
            inside = true;
            outside = vec3<f32>(local.x, 0.0, local.z);
        }
    } else {
        // A cuboid: the box of half extents `shape.xyz` grown by its rounding (the bounding radius less
        // the half extents' length) and the thickness; out from the box's nearest point, or through its
        // nearest face from within the box.
        let half = shape.xyz;
        let rounding = max(centre.w - length(half), 0.0) + thickness;
        let nearest = clamp(local, -half, half);
        let away = local - nearest;
        if dot(away, away) > 0.0 {
            if dot(away, away) < rounding * rounding {
                inside = true;
                outside = nearest + normalize(away) * rounding;
            }
        } else {
            inside = true;
            let q = abs(local) - half;
            if q.x >= q.y && q.x >= q.z {
                outside.x = select(1.0, -1.0, local.x < 0.0) * (half.x + rounding);
            } else if q.y >= q.z {
                outside.y = select(1.0, -1.0, local.y < 0.0) * (half.y + rounding);
            } else {
                outside.z = select(1.0, -1.0, local.z < 0.0) * (half.z + rounding);
            }
        }
    }
    if !inside {
        return world;
    }
    return centre.xyz + rotate(rotation, outside);
}

@compute @workgroup_size(64)
fn frames(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let guide = invocation(id, groups);
    if guide >= params.guides {
        return;
    }
    let first = guide_starts[guide];
    let end = guide_starts[guide + 1u];
    let flags = guide_data[params.guides_offset + 2u * guide + 1u];
    // `place` reads no frames of such a guide.
    if (flags & GUIDE_NO_FRAMES) != 0u || end < first + 2u {
        return;
    }
    var t = normalize(guide_position(first + 1u) - guide_position(first));
    var m1 = decode_director(t, frame_code(first));
    guide_frames[first] = vec4<f32>(m1, 0.0);
    guide_frames[first + 1u] = vec4<f32>(m1, 0.0);
    for (var node = first + 2u; node < end; node++) {
        let next = normalize(guide_position(node) - guide_position(node - 1u));
        let carried = transport(t, next, m1);
        let turn = turn_sin_cos(frame_code(node));
        m1 = perpendicular_unit(turn.y * carried + turn.x * cross(next, carried), next);
        guide_frames[node] = vec4<f32>(m1, 0.0);
        t = next;
    }
}

@compute @workgroup_size(64)
fn place(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let index = invocation(id, groups);
    if index >= params.drawn_nodes {
        return;
    }
    let drawn = drawn_nodes[index];
    let word = drawn.w;
    let node = word & DRAWN_GUIDE_NODE;
    let guide = guide_of_node[node];
    let thickness = bitcast<f32>(guide_data[params.guides_offset + 2u * guide]);
    let flags = guide_data[params.guides_offset + 2u * guide + 1u];
    var position = guide_position(node);
    if (word & DRAWN_GUIDE) == 0u {
        if (flags & GUIDE_NO_FRAMES) == 0u {
            var start = node - 1u;
            if (word & DRAWN_ROOT) != 0u {
                start = node;
            }
            let t = normalize(guide_position(start + 1u) - guide_position(start));
            let m1 = guide_frames[node].xyz;
            let m2 = cross(t, m1);
            let offset = bitcast<vec3<f32>>(drawn.xyz);
            position = position + offset.x * t + offset.y * m1 + offset.z * m2;
        }
        if (word & DRAWN_PUSHED) != 0u {
            for (var collider = 0u; collider < params.colliders; collider++) {
                position = push_out(position, collider, thickness);
            }
        }
    }
    placed[3u * index] = position.x;
    placed[3u * index + 1u] = position.y;
    placed[3u * index + 2u] = position.z;
    if (flags & GUIDE_SNAP) != 0u || params.snap_all != 0u {
        placed_before[3u * index] = position.x;
        placed_before[3u * index + 1u] = position.y;
        placed_before[3u * index + 2u] = position.z;
    }
}

@group(0) @binding(0) var<uniform> draw_params: Params;
@group(0) @binding(1) var<storage, read> draw_before: array<f32>;
@group(0) @binding(2) var<storage, read> draw_after: array<f32>;
@group(0) @binding(3) var<storage, read_write> drawn_positions: array<f32>;

@compute @workgroup_size(64)
fn draw(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let index = invocation(id, groups);
    if index >= draw_params.drawn_nodes {
        return;
    }
    for (var axis = 3u * index; axis < 3u * index + 3u; axis++) {
        let before = draw_before[axis];
        drawn_positions[axis] = before + (draw_after[axis] - before) * draw_params.alpha;
    }
}
