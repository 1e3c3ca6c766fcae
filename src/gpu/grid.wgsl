// Hair–hair interaction on the GPU: each head's hair splatted to a grid around it, the CPU's fields
// (`src/volume/grid.rs` has the equations) computed there, and each node given back its velocity change
// and the pressure's force before the step (`step.wgsl`), all without leaving the GPU. Six dispatches in
// one pass, each seeing the last's writes:
//   1. `bounds`: the box around each stepped head's nodes (sortable-bit atomics);
//   2. `place`: each head's grid points on multiples of the cell in world space (the offset of the head's
//      translation within a cell, `r`, comes from the CPU in double precision), one empty point below the
//      hair and two above as on the CPU, the cells coarsened until they fit the head's share of the buffer;
//   3. `clear`: the points in use zeroed;
//   4. `splat`: every node's momentum, mass, keratin volume and groomed volume spread over its 8 points
//      with trilinear weights, as 64-bit fixed-point sums (two `u32` atomics, carried): WGSL has no float
//      atomics, and a fixed-point sum is exact, so the grid is the same whatever order the nodes land in;
//   5. `fields`: at every point, the smoothing `α`, `α u`, the volume fraction `φ`, the pressure `p` and
//      `max(φ, φ₀)`, in place of the sums;
//   6. `respond`: each free node's velocity change `Σ w α (u − v)` added to its velocity (and to its
//      velocity a step back, as the CPU's `change_velocities`), and the pressure's force
//      `−V Σ w ∇p / max(φ, φ₀)` (central differences) added to its force row, which the step consumes.
// Positions are the state's: world-oriented, relative to the head's translation at the last step's end.

struct Params {
    // The grid's spacing before any coarsening, m; the smoothing rate k, 1/s; the target fraction φ₀;
    // the pressure stiffness K, Pa.
    cell_size: f32,
    smoothing_rate: f32,
    target_fraction: f32,
    stiffness: f32,
    // The fixed-point units of mass (kg) and keratin volume (m³): a sum's value is its 64-bit integer
    // over 2³² units.
    mass_unit: f32,
    volume_unit: f32,
    // 1: the pressure measures packing against the groomed fraction where that is larger (rest row 1 `w`).
    keep_groomed: u32,
    // Strands uploaded; nodes of every strand (a row plane's length); heads; grid points per head.
    strands: u32,
    total_nodes: u32,
    heads: u32,
    points_per_head: u32,
    padding: u32,
}

// As in `step.wgsl`.
const STRAND_FLOATS: u32 = 4u;
// The head's index in a strand's second word (its top bit: whether the strand is free).
const HEAD_INDEX: u32 = 0x7fffffffu;
// Words per head in `grid_heads`: (r as f32 bits ×3, the step's length in s as bits, 0 when the head is
// not stepped), (lowest position ×3 as sortable bits, 0), (highest ×3, 0), (the grid's first point ×3, its
// cell, as f32 bits), (points along X, Y, Z, pressed), (largest φ as bits, 0, 0, 0).
const HEAD_WORDS: u32 = 24u;
// Words per grid point: six fixed-point sums of two words (momentum ×3, mass, volume, groomed volume),
// after `fields` (α u ×3, α, φ, p, max(φ, φ₀)) as f32 bits.
const POINT_WORDS: u32 = 12u;
const WORKGROUP: u32 = 64u;
// Dispatches wider than this many workgroups along X continue along Y (`workgroups` in `step.rs`).
const MAX_GROUPS: u32 = 65535u;
const TWO_32: f32 = 4294967296.0;
// The largest fixed-point magnitude a single node's share may add, in units × 2³² (2⁶²: headroom of 2
// for the sum's sign).
const FIXED_LIMIT: f32 = 4.6e18;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> strand_words: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> strand_floats: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> state: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> grid_heads: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> grid: array<atomic<u32>>;

fn finite(v: f32) -> bool {
    return (bitcast<u32>(v) & 0x7f800000u) != 0x7f800000u;
}

fn finite3(v: vec3<f32>) -> bool {
    return finite(v.x) && finite(v.y) && finite(v.z);
}

// A float's bits, ordered as the floats are (for atomic min and max).
fn sortable(v: f32) -> u32 {
    let bits = bitcast<u32>(v);
    return select(bits | 0x80000000u, ~bits, (bits & 0x80000000u) != 0u);
}

fn unsortable(bits: u32) -> f32 {
    return bitcast<f32>(select(~bits, bits & 0x7fffffffu, (bits & 0x80000000u) != 0u));
}

fn head_word(head: u32, word: u32) -> u32 {
    return atomicLoad(&grid_heads[head * HEAD_WORDS + word]);
}

fn head_float(head: u32, word: u32) -> f32 {
    return bitcast<f32>(head_word(head, word));
}

// The head's step length this fixed step (0: not stepped, so no grid).
fn head_dt(head: u32) -> f32 {
    return head_float(head, 3u);
}

// A node's place in its head's grid frame: its position shifted so that multiples of the cell are world
// multiples.
fn grid_position(head: u32, position: vec3<f32>) -> vec3<f32> {
    return position + vec3<f32>(head_float(head, 0u), head_float(head, 1u), head_float(head, 2u));
}

struct Placement {
    origin: vec3<f32>,
    cell: f32,
    dims: vec3<u32>,
    base: u32,
}

fn placement(head: u32) -> Placement {
    var p: Placement;
    p.origin = vec3<f32>(head_float(head, 12u), head_float(head, 13u), head_float(head, 14u));
    p.cell = head_float(head, 15u);
    p.dims = vec3<u32>(head_word(head, 16u), head_word(head, 17u), head_word(head, 18u));
    p.base = head * params.points_per_head;
    return p;
}

// The lowest of the 8 grid points around `y` and the position in cells, if all 8 are in the grid.
struct Stencil {
    inside: bool,
    corner: vec3<u32>,
    fraction: vec3<f32>,
}

fn stencil(p: Placement, y: vec3<f32>) -> Stencil {
    var s: Stencil;
    let local = (y - p.origin) * (1.0 / p.cell);
    s.inside = finite3(local) && all(local >= vec3<f32>(0.0));
    if !s.inside {
        return s;
    }
    s.corner = vec3<u32>(floor(local));
    s.fraction = local - vec3<f32>(s.corner);
    s.inside = all(s.corner + vec3<u32>(1u) < p.dims);
    return s;
}

// Corner `k` (x fastest) of a stencil: its point's first word and its weight.
fn corner_word(p: Placement, s: Stencil, k: u32) -> u32 {
    let c = s.corner + vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u);
    return (p.base + c.x + p.dims.x * (c.y + p.dims.y * c.z)) * POINT_WORDS;
}

fn corner_weight(s: Stencil, k: u32) -> f32 {
    let upper = vec3<bool>((k & 1u) != 0u, ((k >> 1u) & 1u) != 0u, (k >> 2u) != 0u);
    let w = select(vec3<f32>(1.0) - s.fraction, s.fraction, upper);
    return w.x * w.y * w.z;
}

// Adds `value` units to the 64-bit fixed-point sum at `word` (low word first): the low words' carry
// goes into the high word, so the sum is exact whatever order the additions come in.
fn add_fixed(word: u32, value: f32) {
    let s = min(abs(value) * TWO_32, FIXED_LIMIT);
    let high_part = floor(s * (1.0 / TWO_32));
    // Exact: `s − high · 2³²` is a multiple of `s`'s last bit, below 2³².
    var low = u32(s - high_part * TWO_32);
    var high = u32(high_part);
    if value < 0.0 {
        let borrow = select(0u, 1u, low == 0u);
        low = ~low + 1u;
        high = ~high + borrow;
    }
    if low != 0u {
        let before = atomicAdd(&grid[word], low);
        high += select(0u, 1u, before + low < before);
    }
    if high != 0u {
        atomicAdd(&grid[word + 1u], high);
    }
}

fn read_fixed(word: u32) -> f32 {
    var low = atomicLoad(&grid[word]);
    var high = atomicLoad(&grid[word + 1u]);
    let negative = (high & 0x80000000u) != 0u;
    if negative {
        let borrow = select(0u, 1u, low == 0u);
        low = ~low + 1u;
        high = ~high + borrow;
    }
    let magnitude = f32(high) + f32(low) * (1.0 / TWO_32);
    return select(magnitude, -magnitude, negative);
}

fn store(word: u32, value: f32) {
    atomicStore(&grid[word], bitcast<u32>(value));
}

fn load(word: u32) -> f32 {
    return bitcast<f32>(atomicLoad(&grid[word]));
}

// The strand a workgroup works on (one per strand, lanes over its nodes): its node count, head and first
// node (`strand_words`), and its index; no nodes past the last strand or when its head is not stepped now.
fn grid_strand(group: vec3<u32>) -> vec4<u32> {
    let strand = group.x + group.y * MAX_GROUPS;
    if strand >= params.strands {
        return vec4<u32>(0u);
    }
    let words = strand_words[strand];
    // (The top bit of the head's word says whether the strand is free.)
    let head = words.y & HEAD_INDEX;
    if head_dt(head) <= 0.0 {
        return vec4<u32>(0u);
    }
    return vec4<u32>(words.x, head, words.z, strand);
}

@compute @workgroup_size(64)
fn bounds(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let words = grid_strand(group);
    let head = words.y;
    for (var node = lane; node < words.x; node += WORKGROUP) {
        let x = state[words.z + node].xyz;
        let v = state[params.total_nodes + words.z + node].xyz;
        if !(finite3(x) && finite3(v)) {
            continue;
        }
        let y = grid_position(head, x);
        for (var axis = 0u; axis < 3u; axis++) {
            atomicMin(&grid_heads[head * HEAD_WORDS + 4u + axis], sortable(y[axis]));
            atomicMax(&grid_heads[head * HEAD_WORDS + 8u + axis], sortable(y[axis]));
        }
    }
}

@compute @workgroup_size(64)
fn place(@builtin(global_invocation_id) id: vec3<u32>) {
    let head = id.x;
    if head >= params.heads {
        return;
    }
    let at = head * HEAD_WORDS;
    var dims = vec3<u32>(0u);
    var origin = vec3<f32>(0.0);
    var cell = params.cell_size;
    let low_bits = vec3<u32>(head_word(head, 4u), head_word(head, 5u), head_word(head, 6u));
    let high_bits = vec3<u32>(head_word(head, 8u), head_word(head, 9u), head_word(head, 10u));
    // The CPU resets the lowest to all ones and the highest to 0: a head with no usable node keeps them.
    if head_dt(head) > 0.0 && all(low_bits <= high_bits) {
        let low = vec3<f32>(unsortable(low_bits.x), unsortable(low_bits.y), unsortable(low_bits.z));
        let high = vec3<f32>(unsortable(high_bits.x), unsortable(high_bits.y), unsortable(high_bits.z));
        let budget = f32(params.points_per_head);
        for (var tries = 0u; tries < 64u; tries++) {
            let first = floor(low / cell) - vec3<f32>(1.0);
            let points = floor(high / cell) - first + vec3<f32>(3.0);
            let count = points.x * points.y * points.z;
            if count <= budget {
                origin = first * cell;
                dims = vec3<u32>(points);
                break;
            }
            cell *= pow(count / budget, 1.0 / 3.0) * 1.01;
        }
    }
    atomicStore(&grid_heads[at + 12u], bitcast<u32>(origin.x));
    atomicStore(&grid_heads[at + 13u], bitcast<u32>(origin.y));
    atomicStore(&grid_heads[at + 14u], bitcast<u32>(origin.z));
    atomicStore(&grid_heads[at + 15u], bitcast<u32>(cell));
    atomicStore(&grid_heads[at + 16u], dims.x);
    atomicStore(&grid_heads[at + 17u], dims.y);
    atomicStore(&grid_heads[at + 18u], dims.z);
    atomicStore(&grid_heads[at + 19u], 0u);
    atomicStore(&grid_heads[at + 20u], 0u);
}

// The grid point of a dispatch over every head's share of points, if in use: its head and placement.
fn point_of(id: vec3<u32>, groups: vec3<u32>) -> vec2<u32> {
    let index = id.x + id.y * groups.x * WORKGROUP;
    let head = index / params.points_per_head;
    if head >= params.heads {
        return vec2<u32>(0xffffffffu);
    }
    let p = placement(head);
    let local = index - p.base;
    if local >= p.dims.x * p.dims.y * p.dims.z {
        return vec2<u32>(0xffffffffu);
    }
    return vec2<u32>(head, index);
}

@compute @workgroup_size(64)
fn clear(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let point = point_of(id, groups);
    if point.x == 0xffffffffu {
        return;
    }
    for (var word = 0u; word < POINT_WORDS; word++) {
        atomicStore(&grid[point.y * POINT_WORDS + word], 0u);
    }
}

@compute @workgroup_size(64)
fn splat(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let words = grid_strand(group);
    let strand = words.w;
    let head = words.y;
    if words.x == 0u {
        return;
    }
    let p = placement(head);
    // The hairs the strand stands for, and its keratin's volume per kilogram (1/ρ).
    let hairs = strand_floats[strand * STRAND_FLOATS + 2u].w;
    let per_kilogram = strand_floats[strand * STRAND_FLOATS + 3u].w;
    let groomed_on = select(0.0, 1.0, params.keep_groomed != 0u);
    for (var node = lane; node < words.x; node += WORKGROUP) {
        let x = state[words.z + node].xyz;
        let v = state[params.total_nodes + words.z + node].xyz;
        if !(finite3(x) && finite3(v)) {
            continue;
        }
        let s = stencil(p, grid_position(head, x));
        if !s.inside {
            continue;
        }
        let node_rest = rest[params.total_nodes + words.z + node];
        let mass = hairs * node_rest.y;
        // The root edge's nodes are prescribed: they take part in the volume, not in the smoothing.
        let moving = select(mass, 0.0, node < 2u) / params.mass_unit;
        let volume = mass * per_kilogram / params.volume_unit;
        let groomed = volume * node_rest.w * groomed_on;
        for (var k = 0u; k < 8u; k++) {
            let word = corner_word(p, s, k);
            let w = corner_weight(s, k);
            add_fixed(word, w * moving * v.x);
            add_fixed(word + 2u, w * moving * v.y);
            add_fixed(word + 4u, w * moving * v.z);
            add_fixed(word + 6u, w * moving);
            add_fixed(word + 8u, w * volume);
            add_fixed(word + 10u, w * groomed);
        }
    }
}

@compute @workgroup_size(64)
fn fields(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let point = point_of(id, groups);
    if point.x == 0xffffffffu {
        return;
    }
    let head = point.x;
    let word = point.y * POINT_WORDS;
    let p = placement(head);
    let momentum = vec3<f32>(read_fixed(word), read_fixed(word + 2u), read_fixed(word + 4u));
    let mass = read_fixed(word + 6u);
    let volume = read_fixed(word + 8u) * params.volume_unit;
    let groomed = read_fixed(word + 10u) * params.volume_unit;
    var smoothed = vec3<f32>(0.0);
    var smoothing = 0.0;
    var fraction = 0.0;
    var pressure = 0.0;
    var packing = 0.0;
    if volume > 0.0 {
        let target_fraction = max(groomed / volume, params.target_fraction);
        fraction = volume / (p.cell * p.cell * p.cell);
        let rate = params.smoothing_rate * head_dt(head);
        if mass > 0.0 && rate > 0.0 {
            smoothing = 1.0 - exp(-rate * min(fraction / params.target_fraction, 1.0));
            smoothed = smoothing * momentum / mass;
        }
        if params.stiffness > 0.0 && fraction > target_fraction {
            pressure = params.stiffness * (fraction / target_fraction - 1.0);
            atomicMax(&grid_heads[head * HEAD_WORDS + 19u], 1u);
        }
        packing = max(fraction, target_fraction);
        atomicMax(&grid_heads[head * HEAD_WORDS + 20u], bitcast<u32>(fraction));
    }
    store(word, smoothed.x);
    store(word + 1u, smoothed.y);
    store(word + 2u, smoothed.z);
    store(word + 3u, smoothing);
    store(word + 4u, fraction);
    store(word + 5u, pressure);
    store(word + 6u, packing);
}

// The pressure at point `c` moved by `step` along `axis` (0 outside the grid).
fn pressure_beside(p: Placement, c: vec3<u32>, axis: u32, step: i32) -> f32 {
    var n = vec3<i32>(c);
    n[axis] += step;
    if n[axis] < 0 || n[axis] >= i32(p.dims[axis]) {
        return 0.0;
    }
    let m = vec3<u32>(n);
    return load((p.base + m.x + p.dims.x * (m.y + p.dims.y * m.z)) * POINT_WORDS + 5u);
}

@compute @workgroup_size(64)
fn respond(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let words = grid_strand(group);
    let strand = words.w;
    let head = words.y;
    if words.x == 0u {
        return;
    }
    let p = placement(head);
    let pressed = head_word(head, 19u) != 0u;
    let per_kilogram = strand_floats[strand * STRAND_FLOATS + 3u].w;
    for (var node = lane; node < words.x; node += WORKGROUP) {
        if node < 2u {
            continue;
        }
        let x = state[words.z + node].xyz;
        let v = state[params.total_nodes + words.z + node].xyz;
        if !(finite3(x) && finite3(v)) {
            continue;
        }
        let s = stencil(p, grid_position(head, x));
        if !s.inside {
            continue;
        }
        var smoothed = vec3<f32>(0.0);
        var smoothing = 0.0;
        var push = vec3<f32>(0.0);
        for (var k = 0u; k < 8u; k++) {
            let word = corner_word(p, s, k);
            let w = corner_weight(s, k);
            smoothed += w * vec3<f32>(load(word), load(word + 1u), load(word + 2u));
            smoothing += w * load(word + 3u);
            let fraction = load(word + 4u);
            if pressed && fraction > 0.0 {
                let c = s.corner + vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u);
                var gradient = vec3<f32>(0.0);
                for (var axis = 0u; axis < 3u; axis++) {
                    gradient[axis] = pressure_beside(p, c, axis, 1) - pressure_beside(p, c, axis, -1);
                }
                push += w * gradient * (0.5 / p.cell) / load(word + 6u);
            }
        }
        let change = smoothed - smoothing * v;
        let velocity_at = params.total_nodes + words.z + node;
        state[velocity_at] = vec4<f32>(v + change, state[velocity_at].w);
        let before_at = 3u * params.total_nodes + words.z + node;
        let before = state[before_at];
        state[before_at] = vec4<f32>(before.xyz + change, before.w);
        // The node's keratin volume times the push, added to the forces the step reads (and consumes).
        let volume = rest[params.total_nodes + words.z + node].y * per_kilogram;
        let force_at = 5u * params.total_nodes + words.z + node;
        state[force_at] = vec4<f32>(state[force_at].xyz - volume * push, 0.0);
    }
}
