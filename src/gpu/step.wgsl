// One implicit step of discrete elastic rods (Bergou et al. 2008) per strand, in single precision: the
// CPU's step (`src/rod/solver.rs`) with inextensibility by projection instead of a stiff stretching term
// in the solve (see `src/gpu/mod.rs` for why, and for what differs).
//
// One workgroup per strand, lane `i` owning edge `i` and the node `i + 1` at its end, lane 0 the root
// node too (the strand in the lanes' registers, what lanes share in workgroup memory): a guide of 32 edges
// is one workgroup of 32 lanes, one warp. A free strand (no head holds its root edge) has its first node
// moved like any other, by the lane after its last edge's (so it needs a lane per node). Buffers are row planes of node-contiguous strands:
// row `k` of node `i` of strand `s` is at `k * total_nodes + first(s) + i`, so that a workgroup's lanes
// read neighbouring memory and no strand is padded to the longest. Positions are relative to the
// strand's head (its translation at the end of the last step), so that single precision resolves
// micrometres wherever the head is. Each step:
//   1. shift to the head's new translation; carry the strand rigidly with its root's motion (first guess);
//   2. BDF2's prediction (`x̂ = (4xₙ − xₙ₋₁)/3`, `v̂` alike, `h = ⅔ dt`), backward Euler on the first step;
//   3. Newton iterations on `(M/h² + D/h + (1 + β/dt) H) Δq = −[M (q − x̂ − h v̂)/h² + D ((q − x̂)/h − u)
//      + ∇E + β/dt H (q − q̃) − M g]` over `(x₀, θ⁰, x₁, …)`, the root edge prescribed: assembled one
//      vertex per lane, the band (half-bandwidth 10) in workgroup memory, factorised `L D Lᵀ` column by
//      column with the trailing 10 × 10 update spread over the lanes (the substitutions by one lane), each update within a trust region
//      and the frames carried (time-parallel transport), each followed by a projection onto the edges'
//      rest lengths (Goldenthal et al. 2007) whose tridiagonal system is solved by parallel cyclic
//      reduction: one iteration between Newton iterations, after the last until single precision
//      resolves no better;
//   4. contact: nodes inside a collider (at its end pose, grown by the strand's thickness) put on its
//      surface, with Coulomb friction against their slip over the step relative to the collider, and
//      edges dipping in between their nodes pushed out at their deepest point, then the lengths again,
//      touching nodes moving only along their surfaces, until no node moves by more than its position's
//      rounding;
//   5. checks: a strand with a non-finite value or an edge strained past the bound is put back in its rest
//      pose on its root, at rest, and its status says why;
//   6. velocities `v = (x − x̂)/h` (a node the contact moved keeping no speed away from the surface beyond
//      the surface's own), twist rates by backward Euler, and the history for the next step.
//
// Every decision that ends a loop (a pivot, the projection's error, a contact round) is taken from a
// value all lanes read after a barrier (a reduction over the lanes, a pivot in workgroup memory), so the
// lanes of a strand never diverge around a barrier.

struct Params {
    dt: f32,
    gravity_x: f32,
    gravity_y: f32,
    gravity_z: f32,
    // Air drag γ across the strand, 1/s; drag along it as a fraction of that; internal damping β, s.
    air_damping: f32,
    axial_drag_ratio: f32,
    internal_damping: f32,
    // Largest turn of an edge per Newton update, rad.
    max_rotation: f32,
    // The strain a step may end with (`StepParams::strain_bound`, widened by single precision's floor).
    strain_bound: f32,
    // Stiffness of an edge's first-order change of length in the solve, relative to its nodes' inertia.
    stretch_ratio: f32,
    // Strands uploaded (all lists together).
    strands: u32,
    newton_iterations: u32,
    projection_iterations: u32,
    contact_rounds: u32,
    // 1: BDF2 where a strand has a step of history; 0: backward Euler always.
    bdf2: u32,
    // 1: the first step after an upload or a change of `dt` (no usable history).
    restart: u32,
    // The strain the projection may leave on an edge (`StepParams::strain_tolerance`; single precision's
    // resolution where that is coarser).
    strain_tolerance: f32,
    // Nodes of every strand together: the length of a row plane of `rest` and `state`.
    total_nodes: u32,
    // The strands this dispatch steps: `strand_list[list_start ..][.. list_length]` (the strands whose
    // edges fit this pipeline's lanes).
    list_start: u32,
    list_length: u32,
    // Rows of the air before the heads' in `heads` (`air_at`).
    head_base: u32,
    padding_0: u32,
    padding_1: u32,
    padding_2: u32,
}

// Per strand words: node count, head, its first node in the row planes; and, not the strand's, the `k`th
// strand of the dispatch lists (`list_start`).
const STRAND_WORDS: u32 = 1u;
// The head's index in a strand's second word, and its top bit: the strand is free (no head holds its root
// edge; its head is a frame it is stepped in).
const HEAD_INDEX: u32 = 0x7fffffffu;
const FREE_STRAND: u32 = 0x80000000u;
// Per strand floats: (EA, EI₁, EI₂, GJ); (root node 0 head-local, thickness); (root node 1, the hairs it
// stands for on the hair–hair grid); (root material direction, its keratin's volume per kilogram 1/ρ, m³/kg).
const STRAND_FLOATS: u32 = 4u;
// Rest rows per node: (rest length of edge i, Voronoi length of vertex i, κ̄₁, κ̄₂), (τ̄, mass, twist
// inertia of edge i, the hair volume fraction where the node lay in its groom, for the grid), (rest pose node, θ), (rest pose reference director, reference twist), (the node's
// groomed place for the style hold, head-local; its arc length from the root over the strand's, past 1
// where the strand is not held).
// State rows per node: (position, θ of edge i), (velocity, θ̇), (position a step back, 0), (velocity a step
// back, 0), (reference director of edge i, reference twist at vertex i), (force on the node from outside
// the step, N: the game's (`GpuStrandSolver::add_forces`) and the hair–hair grid's pressure (added by
// `respond` in `grid.wgsl`), 0 after the step reads it; 0), (the air velocity a game adds at the node,
// m/s (`GpuStrandSolver::add_air_velocities`), 0 after the step reads it; 0).
// Per head, after the air's rows (`air_at`): (rotation at the step's end), (shift of the origin:
// translation before − after, 0), (the head's own air velocity, 0), (first collider, colliders as bits, the
// style hold's rate in 1/s and its reach), (rotation at the step's start), (translation at the step's end,
// 0).
const HEAD_ROWS: u32 = 6u;
// Per collider: (centre at the start, relative to its head's new translation; 0), (rotation at the start),
// (centre at the end; friction), (rotation at the end), (shape: sphere (r, 0, 0, 0), capsule (r, half
// length, 0, 1), ellipsoid (semi-axes, 2), plane (0, 0, 0, 3), box (half extents, 4), mesh (its field's
// scale, 5)), (a box's rounding or a mesh's inflation, m; a mesh field's cell, m; the row its samples start
// at, as bits; the shape's least radius of curvature, m), (a mesh field's first sample's position, 0),
// (its samples along X, Y, Z, as bits; 0). Mesh fields' samples follow the colliders, four a row.
const COLLIDER_ROWS: u32 = 8u;

// Lanes per workgroup, one strand each, and so the most edges a strand may have: 32, 64 or 128, set when
// the pipeline is built (`STEP_LANES` in `step.rs`). At 64 the band of 259 unknowns, 11 wide, with what the
// lanes share, fills 15.5 kB of WebGPU's 16 kB of workgroup memory; at 32, 8 kB; at 128, 30.7 kB (built
// where the device has it).
override LANES: u32 = 64u;
const BAND: u32 = 10u;
const WIDTH: u32 = 11u;
override MAX_NODES: u32 = LANES + 1u;
override MAX_DOFS: u32 = 4u * LANES + 3u;
override BAND_FLOATS: u32 = (4u * LANES + 3u) * WIDTH;
// Entries of the trailing update of one column of the factorisation: rows and columns 1 to `BAND` below
// it, at most two a lane.
const UPDATE_ENTRIES: u32 = 55u;

// Status bits (per strand, `status[s].x`): has a step of history; the last step was faulted (non-finite,
// over-strained, not definite) or its contact given up, with the node or edge of the last fault in
// `status[s].y`, `status[s].z` the largest strain as bits, `status[s].w` the failed steps and the last
// one's reason.
const HAS_HISTORY: u32 = 1u;
const FAULT_NON_FINITE: u32 = 2u;
const FAULT_OVER_STRAINED: u32 = 4u;
const FAULT_NOT_DEFINITE: u32 = 8u;
const CONTACT_GIVEN_UP: u32 = 16u;
// The bits of `status[s].x` that are flags; the nodes touching a collider after the step from bit 8 (at
// most 65), the fixed steps the last step spanned from bit 16 (`span`).
const STATUS_FLAGS: u32 = 0xffu;
const CONTACTS_SHIFT: u32 = 8u;
const SPAN_SHIFT: u32 = 16u;
// A head's `span` (the `w` of its sixth row) when its hair is carried with it: out of sight (its velocity
// the head's rigid motion), or waiting for its next step at a coarser level (its own motion kept).
const CARRIED: u32 = 0u;
const WAITING: u32 = 0xffffffffu;
// A collider holding the root this deep inside it leaves this many times the depth of strand free of it.
const HELD_REACH: f32 = 2.0;
// A node this close to a collider's grown surface, m, has a contact spring in the solve (with no force
// until it sinks in); the spring's stiffness relative to the node's inertia: as stiff as `f32` solves
// well (as `STRETCH_RATIO`), a node pressed by its weight sinking `g h² / 10³` (3 µm at 60 Hz).
const CONTACT_GAP: f32 = 2e-6;
const CONTACT_RATIO: f32 = 1e3;
// The bits of `status[s].w` that count failed steps (the reason of the last is in the top four).
const FAULT_COUNT: u32 = 0x0fffffffu;
// Rows of `work` per strand.
const WORK_ROWS: u32 = 2u;
// Single precision's unit roundoff, 2⁻²⁴.
const UNIT_ROUNDOFF: f32 = 5.9604645e-8;
// How many times its rounding an edge's strain is held to by the projection: a position is rounded to
// `u |x|` (head-relative), an edge's length from two of them and a square root to `u (|xᵢ| + |xᵢ₊₁| + 2 l)`;
// four times that is reached in one or two quadratically converging iterations, where the rounding
// itself is not.
const RESOLUTION_MARGIN: f32 = 4.0;
// The error (over the resolution) below which a projection iteration that does not reduce it ends the
// projection: within a hundred times the rounding, the rounding is what is left.
const STALL_EXCESS: f32 = 100.0;
// A node moved by less than this many times its position's rounding has not moved (contact rounds).
const MOVE_MARGIN: f32 = 4.0;
// The bits of +∞: what a reduction takes for a value that is not finite.
const INFINITE_BITS: u32 = 0x7f800000u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> strand_words: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> strand_floats: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> state: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> heads: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> colliders: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> status: array<vec4<u32>>;
// The work each strand's steps took, summed since the upload (wrapping), `WORK_ROWS` rows per strand:
// (steps, Newton iterations, projection iterations, Gauss–Seidel sweeps), (contact rounds, factorisation
// retries, projection iterations that did not reduce the error (single precision's rounding set it),
// projection calls). Read by tests and benchmarks (`GpuStrandSolver::read_work`), never by the step.
@group(0) @binding(8) var<storage, read_write> work: array<vec4<u32>>;

// What the lanes share. The band and right-hand side of the Newton system (the band is the projection's
// scratch between solves: its tridiagonal system and impulses).
var<workgroup> band: array<f32, BAND_FLOATS>;
var<workgroup> rhs: array<f32, MAX_DOFS>;
// Per node: its position (`w` unused).
var<workgroup> shared_x: array<vec4<f32>, MAX_NODES>;
// Per edge: θ.
var<workgroup> shared_theta: array<f32, MAX_NODES>;
// Per edge: (unit tangent, 1/length) in the assembly and the frames' refresh.
var<workgroup> shared_t: array<vec4<f32>, MAX_NODES>;
// Per edge: the material director m₁ in the assembly; the reference director in the frames' refresh. Per
// node: (contact normal, inverse mass) in the projection; the velocity at the write-back.
var<workgroup> shared_m: array<vec4<f32>, MAX_NODES>;
// Reductions over the lanes, and a value one lane says to all.
var<workgroup> reduced: atomic<u32>;
var<workgroup> spoken: u32;

// The strand and this lane's node and edge.
var<private> strand: u32;
var<private> nodes: u32;
var<private> head: u32;
var<private> first: u32;
var<private> lane: u32;
// Whether this lane has an edge (and a node: `node`, at the edge's end).
var<private> own_edge: bool;
var<private> node: u32;
// Whether the strand is free (its root edge not prescribed); whether this lane moves a node (`node`: the
// end of its edge, or a free strand's first node for the lane after the last edge's); whether it holds
// the prescribed root node (`root_x`: lane 0 of a strand that is not free).
var<private> free: bool;
var<private> own_node: bool;
var<private> holds_root: bool;
// Node `node`: position now, at the step's start, the scheme's prediction, the first guess; the tangent
// of the strand there at the step's start; its contact normal and whether it has a contact spring; the
// arc length of rest lengths from the root to it.
var<private> x: vec3<f32>;
var<private> x_start: vec3<f32>;
var<private> x_hat: vec3<f32>;
var<private> v_hat: vec3<f32>;
var<private> v_start: vec3<f32>;
var<private> x_carried: vec3<f32>;
var<private> start_tangent: vec3<f32>;
var<private> normal: vec3<f32>;
var<private> spring: f32;
// The length of this strand's step, s: the fixed step's, or as many of them as its level of detail spans.
var<private> step_dt: f32;
// The air's velocity at this lane's node where it was at the step's start (`air_at`).
var<private> node_air: vec3<f32>;
// The force on this lane's node from outside the step (the hair–hair grid's pressure, `grid.wgsl`), N.
var<private> node_force: vec3<f32>;
// Whether the contact after the solve moved this lane's node this step, and the speed of the collider's
// surface there along `normal` (m/s), for the velocity's inelastic contact.
var<private> pushed: bool;
var<private> surface_speed: f32;
// How far above its collider's surface pushing out an edge left this lane's node in the last step, m (kept
// in the `w` of its state's fourth row; 0 where it did not); whether an edge's push moved it in this one,
// and the collider that did.
var<private> lifted_before: f32;
var<private> lifted: bool;
var<private> lifted_by: u32;
var<private> arc: f32;
// The root node (lane 0's besides node 1, unless the strand is free): prescribed, only carried, loaded
// and stored.
var<private> root_x: vec3<f32>;
var<private> root_hat: vec3<f32>;
var<private> root_carried: vec3<f32>;
// Edge `lane`: θ now, at the step's start, its rate, the first guess; reference director, tangent; the
// reference twist at vertex `lane`.
var<private> theta: f32;
var<private> theta_start: f32;
var<private> theta_rate: f32;
var<private> theta_carried: f32;
var<private> director: vec3<f32>;
var<private> tangent: vec3<f32>;
var<private> reference_twist: f32;
// Vertex `lane`'s bending and twisting gradients over its stencil.
var<private> grad_k1: array<f32, 11>;
var<private> grad_k2: array<f32, 11>;
var<private> grad_tw: array<f32, 11>;
// The entries of the factorisation's trailing update this lane makes (`lane` and `lane + LANES` of the
// 55): rows and columns below the pivot, 0 for none.
var<private> update_rows: vec2<u32>;
var<private> update_columns: vec2<u32>;
// This step's work, added to `work` at the end (every lane counts alike; lane 0 writes).
var<private> work_steps: vec4<u32>;
var<private> work_more: vec4<u32>;

fn rest_at(node: u32, row: u32) -> vec4<f32> {
    return rest[row * params.total_nodes + first + node];
}

fn state_index(node: u32, row: u32) -> u32 {
    return row * params.total_nodes + first + node;
}

fn rotate(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    let b = q.xyz;
    let b2 = dot(b, b);
    return v * (q.w * q.w - b2) + b * (dot(v, b) * 2.0) + cross(b, v) * (q.w * 2.0);
}

fn inverse_rotate(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    return rotate(vec4<f32>(-q.xyz, q.w), v);
}

// `v` carried from the unit tangent `a` to the unit tangent `b` by the smallest rotation (`parallel_transport`).
fn transport(v: vec3<f32>, a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    let axis = cross(a, b);
    let c = dot(a, b);
    if 1.0 + c < 1e-6 {
        let p = any_perpendicular(a);
        return 2.0 * dot(p, v) * p - v;
    }
    return c * v + cross(axis, v) + dot(axis, v) / (1.0 + c) * axis;
}

fn any_perpendicular(t: vec3<f32>) -> vec3<f32> {
    if abs(t.x) < 0.6 {
        return normalize(cross(t, vec3<f32>(1.0, 0.0, 0.0)));
    }
    return normalize(cross(t, vec3<f32>(0.0, 1.0, 0.0)));
}

// `v` made perpendicular to the unit `t` and unit; `fallback` when `v` is along `t`.
fn perpendicular_unit(v: vec3<f32>, t: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let across = v - dot(v, t) * t;
    let size = length(across);
    if size > 1e-6 * length(v) && size > 0.0 {
        return across / size;
    }
    return fallback;
}

fn signed_angle(u: vec3<f32>, v: vec3<f32>, axis: vec3<f32>) -> f32 {
    return atan2(dot(cross(u, v), axis), dot(u, v));
}

fn wrap_angle(a: f32) -> f32 {
    let pi = 3.14159265358979;
    return a - 2.0 * pi * floor((a + pi) / (2.0 * pi));
}

// The air's velocity at `p` (head-relative) at the step's middle: the wind's uniform part, each turbulence
// mode `a cos(k·x + φ)` and each jet (`AirSnapshot::velocity_at`, in the rows before the heads'), and the
// head's own air. `k·x` is taken as `k·p + k·T` (T the head's translation), each in range of `f32`.
fn air_at(p: vec3<f32>) -> vec3<f32> {
    let header = heads[0];
    let modes = bitcast<u32>(header.w);
    let jets = bitcast<u32>(heads[1].x);
    let translation = head_row(5u).xyz;
    var air = header.xyz + head_row(2u).xyz;
    for (var m = 0u; m < modes; m++) {
        let wave = heads[2u + 2u * m];
        air += heads[3u + 2u * m].xyz * cos(dot(wave.xyz, p) + dot(wave.xyz, translation) + wave.w);
    }
    let first_jet = 2u + 2u * modes;
    for (var j = 0u; j < jets; j++) {
        let origin = heads[first_jet + 3u * j];
        let axis = heads[first_jet + 3u * j + 1u];
        let radius = heads[first_jet + 3u * j + 2u].x;
        let offset = p + (translation - origin.xyz);
        let along = dot(offset, axis.xyz);
        if along >= 0.0 && along < axis.w && radius > 0.0 {
            let across = length(offset - along * axis.xyz);
            let width = radius + 0.1 * along;
            let decay = (1.0 - along / axis.w) * (1.0 - along / axis.w);
            air += origin.w * decay * exp(-(across / width) * (across / width)) * axis.xyz;
        }
    }
    return air;
}

fn head_row(row: u32) -> vec4<f32> {
    return heads[params.head_base + head * HEAD_ROWS + row];
}

// The root's targets this step (head-relative): node 0, node 1, the material direction.
fn root_target(row: u32) -> vec3<f32> {
    return rotate(head_row(0u), strand_floats[strand * STRAND_FLOATS + 1u + row].xyz);
}

// The style hold's angular frequency at `along` (the arc length from the root over the strand's), 1/s:
// `rate (1 − smoothstep(along/reach))`, 0 beyond the reach (`HairStyleHold::angular_frequency`).
fn hold_frequency(along: f32) -> f32 {
    let rate = head_row(3u).z;
    let reach = head_row(3u).w;
    if reach <= 0.0 || along >= reach {
        return 0.0;
    }
    let s = along / reach;
    return rate * (1.0 - s * s * (3.0 - 2.0 * s));
}

fn edge_count() -> u32 {
    return nodes - 1u;
}

fn dofs() -> u32 {
    return 4u * nodes - 1u;
}

// Entry (row, column ≤ row) of the band.
fn band_index(row: u32, column: u32) -> u32 {
    return row * WIDTH + BAND - (row - column);
}

// Whether a value is finite, from its bits: WGSL lets an implementation assume no NaN or infinity in
// arithmetic and comparisons, so only the exponent's bits tell reliably.
fn finite(v: f32) -> bool {
    return (bitcast<u32>(v) & 0x7f800000u) != 0x7f800000u;
}

fn finite3(v: vec3<f32>) -> bool {
    return finite(v.x) && finite(v.y) && finite(v.z);
}

// The reductions over the lanes: `reduced` holds 0 between them (for `largest_over_lanes`); each ends
// with every lane's read done (a barrier) before lane 0 resets it. Every lane gets the same value, so the
// decisions taken on it keep the lanes together (WGSL's uniformity analysis cannot see that, and Naga does
// not ask for it).

// The largest of every lane's `value` (not negative; a value that is not finite counts as +∞).
fn largest_over_lanes(value: f32) -> f32 {
    workgroupBarrier();
    atomicMax(&reduced, select(INFINITE_BITS, bitcast<u32>(max(value, 0.0)), finite(value)));
    workgroupBarrier();
    let largest = atomicLoad(&reduced);
    workgroupBarrier();
    if lane == 0u {
        atomicStore(&reduced, 0u);
    }
    return bitcast<f32>(largest);
}

// How many lanes say `yes`.
fn count_over_lanes(yes: bool) -> u32 {
    workgroupBarrier();
    atomicAdd(&reduced, select(0u, 1u, yes));
    workgroupBarrier();
    let count = atomicLoad(&reduced);
    workgroupBarrier();
    if lane == 0u {
        atomicStore(&reduced, 0u);
    }
    return count;
}

// The smallest of every lane's `value`.
fn smallest_over_lanes(value: u32) -> u32 {
    workgroupBarrier();
    if lane == 0u {
        atomicStore(&reduced, 0xffffffffu);
    }
    workgroupBarrier();
    atomicMin(&reduced, value);
    workgroupBarrier();
    let smallest = atomicLoad(&reduced);
    workgroupBarrier();
    if lane == 0u {
        atomicStore(&reduced, 0u);
    }
    return smallest;
}

// Lane 0's `value`, in every lane.
fn from_lane_zero(value: f32) -> f32 {
    workgroupBarrier();
    if lane == 0u {
        spoken = bitcast<u32>(value);
    }
    workgroupBarrier();
    return bitcast<f32>(spoken);
}

// Every lane's node and θ into `shared_x` and `shared_theta`, for its neighbours (lane 0's root node too).
fn publish_nodes() {
    workgroupBarrier();
    if own_node {
        shared_x[node] = vec4<f32>(x, 0.0);
    }
    if own_edge {
        shared_theta[lane] = theta;
    }
    if holds_root {
        shared_x[0] = vec4<f32>(root_x, 0.0);
    }
    workgroupBarrier();
}

// Every lane's node back from `shared_x` (after lane 0 moved them all).
fn take_nodes() {
    workgroupBarrier();
    if own_node {
        x = shared_x[node].xyz;
    }
    workgroupBarrier();
}

// The tangent and material director of each lane's edge from the positions, reference director and twist,
// into `shared_t` and `shared_m` for the vertices beside it.
fn edge_frames() {
    if own_edge {
        let edge = x - shared_x[lane].xyz;
        let size = length(edge);
        let t = edge / size;
        tangent = t;
        let a2 = cross(t, director);
        let m1 = cos(theta) * director + sin(theta) * a2;
        shared_t[lane] = vec4<f32>(t, 1.0 / size);
        shared_m[lane] = vec4<f32>(m1, 0.0);
    }
    workgroupBarrier();
}

// Time-parallel transport of each reference director onto its edge's new tangent, then the reference
// twists, each continued from its last value (`Rod::refresh_frames`).
fn refresh_frames() {
    workgroupBarrier();
    if own_edge {
        let t = normalize(x - shared_x[lane].xyz);
        let carried = transport(director, tangent, t);
        director = perpendicular_unit(carried, t, any_perpendicular(t));
        tangent = t;
        shared_t[lane] = vec4<f32>(t, 0.0);
        shared_m[lane] = vec4<f32>(director, 0.0);
    }
    workgroupBarrier();
    if lane >= 1u && lane < edge_count() {
        let carried = transport(shared_m[lane - 1u].xyz, shared_t[lane - 1u].xyz, tangent);
        let angle = signed_angle(carried, director, tangent);
        reference_twist = reference_twist + wrap_angle(angle - reference_twist);
    }
    workgroupBarrier();
}

// The change of θ⁰ that turns the root edge's m1 onto the root's material direction (lane 0's edge).
fn root_twist_offset(target_tangent: vec3<f32>, direction: vec3<f32>) -> f32 {
    let reference = transport(director, tangent, target_tangent);
    let aim = perpendicular_unit(direction, target_tangent, reference);
    return wrap_angle(signed_angle(reference, aim, target_tangent) - theta);
}

// The strand carried rigidly with its root edge's motion onto the root's targets (`carry_with_first_clamp`):
// the root edge's frame (lane 0's) is said to every lane, each carrying its node and edge.
fn carry_with_root() {
    workgroupBarrier();
    if lane == 0u {
        shared_t[0] = vec4<f32>(tangent, 0.0);
        shared_m[0] = vec4<f32>(cos(theta) * director + sin(theta) * cross(tangent, director), 0.0);
    }
    workgroupBarrier();
    let old_t = shared_t[0].xyz;
    let old_m1 = shared_m[0].xyz;
    let pivot = shared_x[0].xyz;
    workgroupBarrier();
    let p0 = root_target(0u);
    let p1 = root_target(1u);
    let t = normalize(p1 - p0);
    let old_m2 = cross(old_t, old_m1);
    let new_m1 = perpendicular_unit(root_target(2u), t, transport(old_m1, old_t, t));
    let new_m2 = cross(t, new_m1);
    if own_edge {
        let d = x - pivot;
        let local = vec3<f32>(dot(d, old_t), dot(d, old_m1), dot(d, old_m2));
        x = p0 + local.x * t + local.y * new_m1 + local.z * new_m2;
        if node == 1u {
            x = p1;
        }
        let u = director;
        let across = vec3<f32>(dot(u, old_t), dot(u, old_m1), dot(u, old_m2));
        director = across.x * t + across.y * new_m1 + across.z * new_m2;
        let g = tangent;
        let lg = vec3<f32>(dot(g, old_t), dot(g, old_m1), dot(g, old_m2));
        tangent = lg.x * t + lg.y * new_m1 + lg.z * new_m2;
    }
    if holds_root {
        root_x = p0;
    }
    publish_nodes();
}

// Bending and twisting at vertex `lane`: the curvatures' and twist's gradients over the stencil
// `[x_{i−1}, θ^{i−1}, x_i, θ^i, x_{i+1}]` (Bergou et al. 2008 §7; `vertex_strain` in `energy.rs`) into
// `grad_*`, from the edge frames in `shared_t` and `shared_m` (`m₂ = t × m₁`). Returns (κ₁, κ₂, τ).
fn vertex_strain() -> vec3<f32> {
    let i = lane;
    let p = i - 1u;
    let t0 = shared_t[p].xyz;
    let t1 = shared_t[i].xyz;
    let m1p = shared_m[p].xyz;
    let m1i = shared_m[i].xyz;
    let m2p = cross(t0, m1p);
    let m2i = cross(t1, m1i);
    let inverse_chi = 1.0 / (1.0 + dot(t0, t1));
    let binormal = 2.0 * inverse_chi * cross(t0, t1);
    let tilde_t = inverse_chi * (t0 + t1);
    let tilde_m1 = inverse_chi * (m1p + m1i);
    let tilde_m2 = inverse_chi * (m2p + m2i);
    let k1 = 0.5 * dot(binormal, m2p + m2i);
    let k2 = -0.5 * dot(binormal, m1p + m1i);
    let il0 = shared_t[p].w;
    let il1 = shared_t[i].w;
    scatter(0u, (-k1 * tilde_t + cross(t1, tilde_m2)) * il0, (-k1 * tilde_t - cross(t0, tilde_m2)) * il1,
        vec2<f32>(-0.5 * dot(binormal, m1p), -0.5 * dot(binormal, m1i)));
    scatter(1u, (-k2 * tilde_t - cross(t1, tilde_m1)) * il0, (-k2 * tilde_t + cross(t0, tilde_m1)) * il1,
        vec2<f32>(-0.5 * dot(binormal, m2p), -0.5 * dot(binormal, m2i)));
    scatter(2u, 0.5 * binormal * il0, 0.5 * binormal * il1, vec2<f32>(-1.0, 1.0));
    let twist = theta - shared_theta[p] + reference_twist;
    return vec3<f32>(k1, k2, twist);
}

// Node gradients from edge gradients: ∂/∂x_{i−1} = −∂/∂e^{i−1}, ∂/∂x_i = ∂/∂e^{i−1} − ∂/∂e^i, ∂/∂x_{i+1} = ∂/∂e^i.
fn scatter(which: u32, d_previous: vec3<f32>, d_next: vec3<f32>, d_theta: vec2<f32>) {
    let a = -d_previous;
    let b = d_previous - d_next;
    let c = d_next;
    var g = array<f32, 11>(a.x, a.y, a.z, d_theta.x, b.x, b.y, b.z, d_theta.y, c.x, c.y, c.z);
    for (var k = 0u; k < 11u; k++) {
        if which == 0u {
            grad_k1[k] = g[k];
        } else if which == 1u {
            grad_k2[k] = g[k];
        } else {
            grad_tw[k] = g[k];
        }
    }
}

fn node_inverse_mass(i: u32) -> f32 {
    if i < 2u && !free {
        return 0.0;
    }
    return 1.0 / rest_at(i, 1u).y;
}

// The strain single precision resolves on edge `e` at `start`–`end` (positions are head-relative, so the
// further a node is from its head's origin, the coarser it is): `RESOLUTION_MARGIN u ((|xₑ| + |xₑ₊₁|)/l + 2)`,
// 2.4e-5 for a 6 mm edge 0.3 m from the origin, 1e-6 for a 5 cm edge at 0.1 m. Never below the step's
// `strain_tolerance`.
fn strain_resolution(start: vec3<f32>, end: vec3<f32>, rest_length: f32) -> f32 {
    let reach = length(start) + length(end);
    return max(params.strain_tolerance, RESOLUTION_MARGIN * UNIT_ROUNDOFF * (reach / rest_length + 2.0));
}

// The largest edge strain over its resolution (`strain_resolution`), from `shared_x`: at most 1 where
// every edge's length is as exact as single precision can make it.
fn largest_excess() -> f32 {
    var excess = 0.0;
    if own_edge {
        let start = shared_x[lane].xyz;
        let end = shared_x[lane + 1u].xyz;
        let rest_length = rest_at(lane, 0u).x;
        excess = abs(length(end - start) / rest_length - 1.0) / strain_resolution(start, end, rest_length);
    }
    return largest_over_lanes(excess);
}

// This lane's edge strain (0 for a lane without an edge), from `shared_x`.
fn edge_strain() -> f32 {
    if !own_edge {
        return 0.0;
    }
    return abs(length(shared_x[lane + 1u].xyz - shared_x[lane].xyz) / rest_at(lane, 0u).x - 1.0);
}

// The largest edge strain and the first edge that has it (a strain that is not finite the largest).
fn largest_strain() -> vec2<f32> {
    let strain = edge_strain();
    let worst = largest_over_lanes(strain);
    let bits = select(INFINITE_BITS, bitcast<u32>(strain), finite(strain));
    let mine = own_edge && bits == bitcast<u32>(worst);
    let edge = smallest_over_lanes(select(0xffffffffu, lane, mine));
    return vec2<f32>(worst, f32(min(edge, edge_count() - 1u)));
}

// Node `i`'s move for a push `v`: `M⁻¹ v`, along its contact surface where it touches one (from
// `shared_m`, filled by `share_mobility`).
fn mobility(i: u32, v: vec3<f32>) -> vec3<f32> {
    let n = shared_m[i].xyz;
    return shared_m[i].w * (v - dot(n, v) * n);
}

// Every node's contact normal and inverse mass into `shared_m`, for `mobility`.
fn share_mobility() {
    workgroupBarrier();
    if own_node {
        shared_m[node] = vec4<f32>(normal, node_inverse_mass(node));
    }
    if holds_root {
        shared_m[0] = vec4<f32>(0.0);
    }
    workgroupBarrier();
}

// The projection's tridiagonal system in the band's place: lower, diagonal, upper and right-hand side of
// equation `e` at `band[e]`, `band[LANES + e]`, … (the band is not needed between solves).
const TRI_LOWER: u32 = 0u;
override TRI_DIAGONAL: u32 = LANES;
override TRI_UPPER: u32 = 2u * LANES;
override TRI_RHS: u32 = 3u * LANES;
// Each edge's impulse in the projection, `band[IMPULSE + 4e ..]`.
override IMPULSE: u32 = 4u * LANES;

// Solves the tridiagonal system held in the band's place (one equation per edge's lane, in its
// registers: `a`, `b`, `c`, `d`) by parallel cyclic reduction (Hockney 1965): each round eliminates the
// equations `s` away on either side, doubling `s`, until every equation stands alone. Returns this lane's
// unknown.
fn cyclic_reduction(a_in: f32, b_in: f32, c_in: f32, d_in: f32) -> f32 {
    let edges = edge_count();
    var a = a_in;
    var b = b_in;
    var c = c_in;
    var d = d_in;
    for (var s = 1u; s < edges; s = s * 2u) {
        workgroupBarrier();
        if own_edge {
            band[TRI_LOWER + lane] = a;
            band[TRI_DIAGONAL + lane] = b;
            band[TRI_UPPER + lane] = c;
            band[TRI_RHS + lane] = d;
        }
        workgroupBarrier();
        if own_edge {
            var next_a = 0.0;
            var next_c = 0.0;
            var next_b = b;
            var next_d = d;
            if lane >= s {
                let below = lane - s;
                let alpha = -a / band[TRI_DIAGONAL + below];
                next_a = alpha * band[TRI_LOWER + below];
                next_b += alpha * band[TRI_UPPER + below];
                next_d += alpha * band[TRI_RHS + below];
            }
            if lane + s < edges {
                let above = lane + s;
                let gamma = -c / band[TRI_DIAGONAL + above];
                next_c = gamma * band[TRI_UPPER + above];
                next_b += gamma * band[TRI_LOWER + above];
                next_d += gamma * band[TRI_RHS + above];
            }
            a = next_a;
            b = next_b;
            c = next_c;
            d = next_d;
        }
    }
    return d / b;
}

// Fast projection onto the rest lengths (Goldenthal et al. 2007): `x ← x − M⁻¹ ∇Cᵀ λ` with the tridiagonal
// `(∇C M⁻¹ ∇Cᵀ) λ = C`, `C_j = e_j·e_j / L_j − L_j` (one equation per edge's lane, by cyclic reduction); a
// Gauss–Seidel sweep of exact per-edge projections where a Newton step would not reduce the error.
// Touching nodes move only along their surfaces. Stops once every edge is within the strain single
// precision resolves where it lies (`strain_resolution`), or when an iteration, sweep included, no
// longer reduces an error within `STALL_EXCESS` of it (rounding, not the lengths, sets it then). Reads and
// leaves the nodes in `shared_x` and the lanes' `x`.
fn project_lengths(iterations: u32) {
    let edges = edge_count();
    share_mobility();
    var error = largest_excess();
    work_more.w += 1u;
    for (var iteration = 0u; iteration < iterations; iteration++) {
        if error <= 1.0 {
            return;
        }
        work_steps.z += 1u;
        // Equation `lane`: its diagonal, its coupling to the next edge, and whether the edge can move.
        var a = 0.0;
        var b = 1.0;
        var c = 0.0;
        var d = 0.0;
        var edge = vec3<f32>(0.0);
        var goal = 1.0;
        var movable = false;
        if own_edge {
            edge = shared_x[lane + 1u].xyz - shared_x[lane].xyz;
            goal = rest_at(lane, 0u).x;
            let k = 4.0 * dot(edge, mobility(lane, edge) + mobility(lane + 1u, edge)) / (goal * goal);
            let free_k = 4.0 * dot(edge, edge) / (goal * goal)
                * (node_inverse_mass(lane) + node_inverse_mass(lane + 1u));
            movable = k > 1e-6 * free_k && k > 0.0;
            if movable {
                // The slight excess keeps the system definite where edges fold onto one line. Each
                // iteration leaves that excess times the system's condition (as the edges squared: 2.3e4
                // for a straight chain of 128 edges, 6.9e4 for 256) of the smoothest error: 0.23 and
                // 0.69 of it. (The CPU's 1e-6, tried, took the wind-blown 128 edges of
                // `tests/gpu/step.rs` from 18.6 projection iterations a step to 17.2, but left a node of
                // the character's hair 1.25 mm inside its face, against 0.17 mm: three strands' contact
                // given up where two were.)
                b = k * (1.0 + 1e-5);
                d = dot(edge, edge) / goal - goal;
            }
            if lane + 1u < edges {
                let next = shared_x[lane + 2u].xyz - shared_x[lane + 1u].xyz;
                c = -4.0 * dot(edge, mobility(lane + 1u, next)) / (goal * rest_at(lane + 1u, 0u).x);
            }
        }
        // An edge that cannot move is an equation of its own (λ = 0), and its neighbours' coupling to it 0.
        workgroupBarrier();
        if own_edge {
            band[TRI_UPPER + lane] = c;
            band[TRI_DIAGONAL + lane] = select(0.0, 1.0, movable);
        }
        workgroupBarrier();
        if own_edge {
            if lane > 0u {
                a = band[TRI_UPPER + lane - 1u];
                if band[TRI_DIAGONAL + lane - 1u] == 0.0 {
                    a = 0.0;
                }
            }
            if lane + 1u < edges && band[TRI_DIAGONAL + lane + 1u] == 0.0 {
                c = 0.0;
            }
            if !movable {
                a = 0.0;
                c = 0.0;
            }
        }
        let lambda = cyclic_reduction(a, b, c, d);
        // The impulses from the edges as they were.
        workgroupBarrier();
        if own_edge {
            let impulse = 2.0 * lambda / goal * edge;
            band[IMPULSE + 4u * lane] = impulse.x;
            band[IMPULSE + 4u * lane + 1u] = impulse.y;
            band[IMPULSE + 4u * lane + 2u] = impulse.z;
        }
        workgroupBarrier();
        // Node `node` at the end of edge `node − 1` and the start of edge `node` (a root held on its head
        // does not move).
        if own_node {
            var push = vec3<f32>(0.0);
            if node > 0u {
                let e = node - 1u;
                push -= vec3<f32>(band[IMPULSE + 4u * e], band[IMPULSE + 4u * e + 1u], band[IMPULSE + 4u * e + 2u]);
            }
            if node < edges {
                push += vec3<f32>(band[IMPULSE + 4u * node], band[IMPULSE + 4u * node + 1u], band[IMPULSE + 4u * node + 2u]);
            }
            x += mobility(node, push);
        }
        publish_nodes();
        var projected = largest_excess();
        if !(projected < error) {
            gauss_seidel_sweep();
            work_steps.w += 1u;
            projected = largest_excess();
            // Stalled near the resolution: rounding sets the error there, and more iterations do not
            // lower it. Further from it (nodes held on colliders' surfaces fighting the lengths), go on.
            if !(projected < error) {
                work_more.z += 1u;
                // (Not where an edge is strained past half the step's bound: short edges far from the
                // head's origin resolve coarsely, and `STALL_EXCESS` of their resolution can pass the
                // bound: 256 edges of 1.6 mm, on a 256-lane pipeline tried, stopped there at 3.1e-3 and
                // failed the step.)
                if projected <= STALL_EXCESS && largest_over_lanes(edge_strain()) <= 0.5 * params.strain_bound {
                    return;
                }
            }
        }
        error = projected;
    }
}

// The most projection iterations to single precision's resolution: the step's limit, and past 64 edges in
// proportion to the square of the edges (as the condition of the lengths' tridiagonal system). Each
// iteration solves the lengths' linearisation exactly, but in `f32` the longer the chain, the worse that
// system's condition and the more iterations it takes. Soft strands let go horizontal were over-strained
// at 16 iterations from 96 edges on (96, 128, 200 and 256 edges of 2 to 5 mm); 128 edges of 2.3 mm blown
// sideways by a 1.6 m/s wind needed 48 iterations over a step's two projections, and were over-strained
// at a limit of 32 (16 per 64 edges). The iterations stop earlier wherever the lengths are resolved or the
// error stalls.
fn projection_limit() -> u32 {
    let edges = edge_count();
    return max(params.projection_iterations, (params.projection_iterations * edges * edges + 4095u) / 4096u);
}

// Exact per-edge projections, root to tip and back, by lane 0 on `shared_x` (the fallback of a
// projection iteration that did not reduce the error; each edge depends on the last).
fn gauss_seidel_sweep() {
    workgroupBarrier();
    if lane == 0u {
        let edges = edge_count();
        for (var sweep = 0u; sweep < 2u * edges; sweep++) {
            let e = select(2u * edges - 1u - sweep, sweep, sweep < edges);
            let d = shared_x[e + 1u].xyz - shared_x[e].xyz;
            let size = length(d);
            if size == 0.0 {
                continue;
            }
            let direction = d / size;
            let start_move = mobility(e, direction);
            let end_move = mobility(e + 1u, direction);
            let total = dot(direction, start_move + end_move);
            if total <= 1e-9 * (node_inverse_mass(e) + node_inverse_mass(e + 1u)) {
                continue;
            }
            let excess = (size - rest_at(e, 0u).x) / total;
            shared_x[e] = vec4<f32>(shared_x[e].xyz + excess * start_move, 0.0);
            shared_x[e + 1u] = vec4<f32>(shared_x[e + 1u].xyz - excess * end_move, 0.0);
        }
    }
    take_nodes();
}

// Whether collider `c` meets this lane's node (from the third: the root edge is prescribed; every node of
// a free strand). A collider holding the root inside it leaves the nodes within `HELD_REACH` times the
// root's depth (along the strand) free of it, as on the CPU (`held_reach` in `rod/contact.rs`): hair
// grows out of it, and is not torn trying to be outside.
fn meets(c: u32, thickness: f32) -> bool {
    return own_node && (free || (node >= 2u && arc > held_reach(c, thickness)));
}

// How far along the strand from its root collider `c` leaves the strand free of it: `HELD_REACH` times the
// root's depth inside it (0 where the root is outside).
fn held_reach(c: u32, thickness: f32) -> f32 {
    return HELD_REACH * max(-touch(c, shared_x[0].xyz, thickness, 0.0).distance, 0.0);
}

// Contact inside the solve, as on the CPU (`rod/contact.rs`): this lane's node, within `CONTACT_GAP` of a
// collider (at its end pose, grown by the thickness), gets a stiff one-sided spring along the surface
// normal, `½ k min(d, 0)²` with `k = CONTACT_RATIO m (1/h² + γ/h)`, so that the solve knows what supports
// the strand (a node pressed by its weight sinks `g h² / CONTACT_RATIO`). `spring` says whether it has
// one, for the friction.
fn add_contact_springs(inertia: f32) {
    let first_collider = bitcast<u32>(head_row(3u).x);
    let count = bitcast<u32>(head_row(3u).y);
    let thickness = strand_floats[strand * STRAND_FLOATS + 1u].w;
    spring = 0.0;
    for (var k = 0u; k < count; k++) {
        let c = first_collider + k;
        if !meets(c, thickness) {
            continue;
        }
        // A node that pushing out an edge left above the surface in the last step keeps its spring that
        // far out (and half as far again), with no force until it sinks in, rather than falling a step's
        // worth and being pushed out again: hair resting across a curved collider comes to rest.
        let gap = CONTACT_GAP + 1.5 * lifted_before;
        let contact = touch(c, x, thickness, gap);
        if contact.distance >= gap {
            continue;
        }
        let i = node;
        let stiffness = CONTACT_RATIO * rest_at(i, 1u).y * inertia;
        let n = contact.normal;
        let pressed = stiffness * min(contact.distance, 0.0);
        for (var a = 0u; a < 3u; a++) {
            rhs[4u * i + a] += pressed * n[a];
            for (var b = 0u; b <= a; b++) {
                band[band_index(4u * i + a, 4u * i + b)] += stiffness * n[a] * n[b];
            }
        }
        spring = 1.0;
    }
}

// Assembles the Newton system at the current iterate and factorises it; returns false where it does not
// factorise even with the diagonal scaled by `1 + λ`, λ up to 1.
fn assemble_and_factorize(iteration: u32, h: f32, target_offset: f32) -> bool {
    let n = dofs();
    let edges = edge_count();
    let vertex = lane >= 1u && lane < edges;
    var regularisation = 0.0;
    loop {
        workgroupBarrier();
        for (var k = lane; k < n * WIDTH; k += LANES) {
            band[k] = 0.0;
        }
        edge_frames();
        // Vertex `lane`'s bending and twisting: its forces `f`, stiffnesses `s` (over its Voronoi length),
        // and internal damping `β/dt H (q − q̃)` on the deformation since the first guess, `g (g · Δq)`.
        let stiffness = strand_floats[strand * STRAND_FLOATS];
        var force = vec3<f32>(0.0);
        var scaled = vec3<f32>(0.0);
        if vertex {
            let strain = vertex_strain();
            let rest_bend = rest_at(lane, 0u);
            let rest_twist = rest_at(lane, 1u).x;
            scaled = stiffness.yzw / rest_bend.y;
            force = scaled * (strain - vec3<f32>(rest_bend.zw, rest_twist));
        }
        if iteration > 0u && params.internal_damping > 0.0 {
            if own_node {
                let offset = x - x_carried;
                rhs[4u * node] = offset.x;
                rhs[4u * node + 1u] = offset.y;
                rhs[4u * node + 2u] = offset.z;
            }
            if own_edge {
                rhs[4u * lane + 3u] = theta - theta_carried;
            }
            if holds_root {
                let offset = root_x - root_carried;
                rhs[0] = offset.x;
                rhs[1] = offset.y;
                rhs[2] = offset.z;
            }
            workgroupBarrier();
            if vertex {
                let offset = 4u * (lane - 1u);
                var along = vec3<f32>(0.0);
                for (var a = 0u; a < 11u; a++) {
                    let d = rhs[offset + a];
                    along += vec3<f32>(grad_k1[a], grad_k2[a], grad_tw[a]) * d;
                }
                force += params.internal_damping / step_dt * scaled * along;
            }
            workgroupBarrier();
        }
        for (var k = lane; k < n; k += LANES) {
            rhs[k] = 0.0;
        }
        workgroupBarrier();
        // Vertices three apart share no unknowns: three passes, each adding a third of them.
        let damped_scale = 1.0 + params.internal_damping / step_dt;
        for (var colour = 0u; colour < 3u; colour++) {
            if vertex && lane % 3u == colour {
                let offset = 4u * (lane - 1u);
                let w = damped_scale * scaled;
                for (var a = 0u; a < 11u; a++) {
                    rhs[offset + a] += force.x * grad_k1[a] + force.y * grad_k2[a] + force.z * grad_tw[a];
                    let row = offset + a;
                    for (var b = 0u; b <= a; b++) {
                        band[band_index(row, offset + b)] +=
                            w.x * grad_k1[a] * grad_k1[b] + w.y * grad_k2[a] * grad_k2[b] + w.z * grad_tw[a] * grad_tw[b];
                    }
                }
            }
            workgroupBarrier();
        }
        // Node `node`'s own rows: the capped stretching stiffness of its edges' first-order change of
        // length (`k t tᵀ` on both nodes' diagonal blocks, `−k t tᵀ` between them; no stretching force:
        // lengths are the projection's), inertia, drag relative to the air, gravity, the style hold,
        // contact springs; and edge `lane`'s twist inertia. (A held root node's rows are prescribed: none.)
        let inertia = 1.0 / (h * h) + params.air_damping / h;
        if own_node {
            let i = node;
            let stretching = strand_floats[strand * STRAND_FLOATS].x;
            for (var side = 0u; side < 2u; side++) {
                // Edge i − 1 (side 0) and edge i (side 1).
                if (side == 0u && i == 0u) || (side == 1u && i >= edges) {
                    continue;
                }
                let e = i + side - 1u;
                let rest_length = rest_at(e, 0u).x;
                let mass = 0.5 * (rest_at(e, 1u).y + rest_at(e + 1u, 1u).y);
                let k = min(stretching / rest_length, params.stretch_ratio * mass * inertia);
                let t = shared_t[e].xyz;
                for (var a = 0u; a < 3u; a++) {
                    for (var b = 0u; b < 3u; b++) {
                        let value = k * t[a] * t[b];
                        if side == 0u {
                            band[band_index(4u * i + a, 4u * e + b)] -= value;
                        }
                        if b <= a {
                            band[band_index(4u * i + a, 4u * i + b)] += value;
                        }
                    }
                }
            }
            let gravity = vec3<f32>(params.gravity_x, params.gravity_y, params.gravity_z);
            let air = node_air;
            let mass = rest_at(i, 1u).y;
            let offset = x - x_hat;
            let relative = offset / h - air;
            let t = start_tangent;
            let gamma = mass * params.air_damping;
            let along = 1.0 - params.axial_drag_ratio;
            let drag_force = gamma * (relative - along * dot(t, relative) * t);
            var residual = mass / (h * h) * (offset - h * v_hat) + drag_force - mass * gravity - node_force;
            var diagonal = mass / (h * h) + gamma / h;
            // The style hold: `m k (x − x̄) + m c (v − v̄)` towards the groomed place carried with the head
            // (`Anchor` on the CPU); the root edge is prescribed.
            let held = rest_at(i, 4u);
            let frequency = hold_frequency(held.w);
            if frequency > 0.0 && i >= 2u {
                let k = frequency * frequency;
                let c = 2.0 * frequency;
                let place = rotate(head_row(0u), held.xyz);
                let place_velocity = (place - rotate(head_row(4u), held.xyz) - head_row(1u).xyz) / params.dt;
                residual += mass * k * (x - place) + mass * c * (offset / h - place_velocity);
                diagonal += mass * (k + c / h);
            }
            for (var a = 0u; a < 3u; a++) {
                rhs[4u * i + a] += residual[a];
                for (var b = 0u; b <= a; b++) {
                    var value = gamma / h * (-along * t[a] * t[b]);
                    if a == b {
                        value += diagonal;
                    }
                    band[band_index(4u * i + a, 4u * i + b)] += value;
                }
            }
            add_contact_springs(inertia);
        }
        if own_edge {
            // Edge `lane`'s twist by backward Euler.
            {
                let dt = step_dt;
                let j = rest_at(lane, 1u).z;
                let twist_offset = theta - theta_start;
                let dof = 4u * lane + 3u;
                rhs[dof] += j / (dt * dt) * (twist_offset - dt * theta_rate) + params.air_damping * j / dt * twist_offset;
                band[band_index(dof, dof)] += j * (1.0 / (dt * dt) + params.air_damping / dt);
            }
        }
        workgroupBarrier();
        if regularisation > 0.0 {
            for (var k = lane; k < n; k += LANES) {
                band[band_index(k, k)] *= 1.0 + regularisation;
            }
            workgroupBarrier();
        }
        // The root edge prescribed (a strand held on its head): its unknowns move by their remaining
        // displacement, and the rows below them feel it. (Every lane takes the same branch.)
        if !free {
            let p0 = root_target(0u) - shared_x[0].xyz;
            let p1 = root_target(1u) - shared_x[1].xyz;
            var prescribed = array<f32, 7>(p0.x, p0.y, p0.z, target_offset, p1.x, p1.y, p1.z);
            let coupled = min(n, 7u + BAND);
            if lane < coupled {
                let r = lane;
                var coupling = 0.0;
                for (var c = 0u; c < 7u; c++) {
                    if r >= c && r - c <= BAND {
                        coupling += band[band_index(r, c)] * prescribed[c];
                    } else if c > r && c - r <= BAND {
                        coupling += band[band_index(c, r)] * prescribed[c];
                    }
                }
                rhs[r] += coupling;
            }
            workgroupBarrier();
            if lane < coupled {
                let r = lane;
                for (var c = select(0u, r - BAND, r >= BAND); c < min(r, 7u); c++) {
                    band[band_index(r, c)] = 0.0;
                }
                if r < 7u {
                    band[band_index(r, r)] = 1.0;
                    rhs[r] = -prescribed[r];
                }
            }
        }
        if factorize() {
            return true;
        }
        if regularisation >= 1.0 {
            return false;
        }
        regularisation = max(100.0 * regularisation, 1e-6);
        work_more.y += 1u;
    }
    return false;
}

// `L D Lᵀ` of the band in place, right-looking: for each column, its pivot `d` read by every lane, then
// the 10 × 10 triangle below it updated by as many lanes, `A_im −= A_ij A_mj / d`. The column is left as
// `L_ij d` (the solves divide), so one barrier a column. False at a non-positive pivot (every lane reads
// the same pivot, so all return together).
fn factorize() -> bool {
    let n = dofs();
    for (var j = 0u; j < n; j++) {
        workgroupBarrier();
        let d = band[band_index(j, j)];
        if !(d > 0.0) || !finite(d) {
            workgroupBarrier();
            return false;
        }
        for (var k = 0u; k < 2u; k++) {
            let i = j + update_rows[k];
            let m = j + update_columns[k];
            if update_rows[k] > 0u && i < n {
                band[band_index(i, m)] -= band[band_index(i, j)] * band[band_index(m, j)] / d;
            }
        }
    }
    return true;
}

// Solves `L D Lᵀ y = rhs` in place (`L_ij = band(i, j) / d_j`, `d_j = band(j, j)`), by lane 0 alone: the
// substitutions are chains of dependent steps (ten multiply-adds a row), which lanes would only pass to
// each other through a barrier a row. Forward and diagonal together, `y_i = (rhs_i − Σ_k band(i, k) y_k) / d_i`;
// backward `x_i = y_i − Σ_k band(k, i) x_k / d_i`.
fn solve() {
    let n = dofs();
    workgroupBarrier();
    if lane == 0u {
        for (var i = 0u; i < n; i++) {
            var sum = rhs[i];
            for (var k = select(0u, i - BAND, i >= BAND); k < i; k++) {
                sum -= band[band_index(i, k)] * rhs[k];
            }
            rhs[i] = sum / band[band_index(i, i)];
        }
        for (var step = 0u; step < n; step++) {
            let i = n - 1u - step;
            var sum = 0.0;
            for (var k = i + 1u; k <= min(i + BAND, n - 1u); k++) {
                sum += band[band_index(k, i)] * rhs[k];
            }
            rhs[i] -= sum / band[band_index(i, i)];
        }
    }
    workgroupBarrier();
}

// Where a point meets a collider grown by the strand's thickness: the signed distance (negative inside),
// the closest surface point and the outward normal there. Exact within the `gap` asked for (of
// `touch_local`); further out the distance is a lower bound (`distance_bound`) and the point and normal
// are not to be used.
struct Touch {
    distance: f32,
    surface: vec3<f32>,
    normal: vec3<f32>,
}

fn collider_row(c: u32, row: u32) -> vec4<f32> {
    return colliders[c * COLLIDER_ROWS + row];
}

// Sample `index` of the distance field whose samples start at row `base` of the collider buffer (four a
// row, X fastest).
fn field_sample(base: u32, index: u32) -> f32 {
    let row = colliders[base + index / 4u];
    return row[index % 4u];
}

// A mesh collider's baked field at `q` (the field's own frame): the trilinear distance and its gradient
// `(d, ∇d)`; outside the grid, `max(|q − c|, d(c) − |q − c|)` from the grid's nearest point `c`
// (`DistanceField::distance_and_gradient`).
fn field_distance(c: u32, q: vec3<f32>) -> vec4<f32> {
    let extra = collider_row(c, 5u);
    let cell = extra.y;
    let base = bitcast<u32>(extra.z);
    let low = collider_row(c, 6u).xyz;
    let counts = bitcast<vec3<u32>>(collider_row(c, 7u).xyz);
    let high = low + vec3<f32>(counts - vec3<u32>(1u)) * cell;
    let inner = clamp(q, low, high);
    let local = (inner - low) / cell;
    let corner = min(vec3<u32>(max(floor(local), vec3<f32>(0.0))), counts - vec3<u32>(2u));
    let f = clamp(local - vec3<f32>(corner), vec3<f32>(0.0), vec3<f32>(1.0));
    let start = corner.x + counts.x * (corner.y + counts.y * corner.z);
    let dy = counts.x;
    let dz = counts.x * counts.y;
    // Along X on the cell's four X edges, then Y, then Z.
    let a00 = field_sample(base, start);
    let b00 = field_sample(base, start + 1u);
    let a10 = field_sample(base, start + dy);
    let b10 = field_sample(base, start + dy + 1u);
    let a01 = field_sample(base, start + dz);
    let b01 = field_sample(base, start + dz + 1u);
    let a11 = field_sample(base, start + dy + dz);
    let b11 = field_sample(base, start + dy + dz + 1u);
    let x00 = mix(a00, b00, f.x);
    let x10 = mix(a10, b10, f.x);
    let x01 = mix(a01, b01, f.x);
    let x11 = mix(a11, b11, f.x);
    let y0 = mix(x00, x10, f.y);
    let y1 = mix(x01, x11, f.y);
    let distance = mix(y0, y1, f.z);
    let along_x = mix(mix(b00 - a00, b10 - a10, f.y), mix(b01 - a01, b11 - a11, f.y), f.z);
    let along_y = mix(x10 - x00, x11 - x01, f.z);
    let gradient = vec3<f32>(along_x, along_y, y1 - y0) / cell;
    let away = q - inner;
    let gap = length(away);
    if gap > 0.0 {
        return vec4<f32>(max(gap, distance - gap), away / gap);
    }
    return vec4<f32>(distance, gradient);
}

// A mesh collider's signed distance at `local` (its frame, m) grown by `grown` m, and its gradient: the
// field at `local / scale` taken at the least scale (`mesh_distance` on the CPU).
fn mesh_distance(c: u32, local: vec3<f32>, grown: f32) -> vec4<f32> {
    let scale = collider_row(c, 4u).xyz;
    let least = min(scale.x, min(scale.y, scale.z));
    let field = field_distance(c, local / scale);
    return vec4<f32>(field.x * least - grown, field.yzw / scale * least);
}

// The signed distance of box `|x_i| ≤ h_i` (negative inside): `|max(q, 0)| + min(max_i q_i, 0)`,
// `q = |p| − h` (Quílez, "distance functions").
fn box_distance(h: vec3<f32>, p: vec3<f32>) -> f32 {
    let q = abs(p) - h;
    return length(max(q, vec3<f32>(0.0))) + min(max(q.x, max(q.y, q.z)), 0.0);
}

// A lower bound on the signed distance from `local` (collider `c`'s frame) to its surface grown by
// `thickness`, m: exact but for ellipsoids (the gap between the surface and its scaling through `local`)
// and meshes (the interpolated field). Cheap: it rules out what cannot touch.
fn distance_bound(c: u32, local: vec3<f32>, thickness: f32) -> f32 {
    let shape = collider_row(c, 4u);
    let kind = u32(shape.w);
    switch kind {
        case 0u: {
            return length(local) - shape.x - thickness;
        }
        case 1u: {
            let axis = vec3<f32>(0.0, clamp(local.y, -shape.y, shape.y), 0.0);
            return length(local - axis) - shape.x - thickness;
        }
        case 2u: {
            let axes = shape.xyz + vec3<f32>(thickness);
            let scale = length(local / axes);
            let axis = select(max(axes.x, max(axes.y, axes.z)), min(axes.x, min(axes.y, axes.z)), scale >= 1.0);
            return (scale - 1.0) * axis;
        }
        case 3u: {
            return local.y - thickness;
        }
        case 4u: {
            return box_distance(shape.xyz, local) - collider_row(c, 5u).x - thickness;
        }
        default: {
            return mesh_distance(c, local, collider_row(c, 5u).x + thickness).x;
        }
    }
}

// The closest point on the ellipsoid with semi-axes `a` to `p`: `x_i = a_i² p_i / (a_i² + λ)` where
// `F(λ) = Σ (a_i p_i / (a_i² + λ))² − 1 = 0` (Eberly, "Distance from a point to an ellipsoid"), by
// Newton's method safeguarded with bisection on `λ ∈ (−a_min², |a ∘ p|]`; radially for a point on a
// symmetry plane through the centre, where `F` has no pole (`closest_ellipsoid_point` on the CPU).
fn closest_on_ellipsoid(a: vec3<f32>, p: vec3<f32>) -> Touch {
    let squared = a * a;
    let smallest = min(squared.x, min(squared.y, squared.z));
    var low = -smallest;
    var high = max(length(a * p), 0.0);
    var lambda = clamp(0.0, low, high);
    for (var k = 0u; k < 32u; k++) {
        let denominator = squared + vec3<f32>(lambda);
        let scaled = a * p / denominator;
        let f = dot(scaled, scaled) - 1.0;
        let derivative = -2.0 * dot(scaled * scaled, vec3<f32>(1.0) / denominator);
        if f > 0.0 {
            low = lambda;
        } else {
            high = lambda;
        }
        if abs(f) < 4.0 * UNIT_ROUNDOFF || high - low <= 4.0 * UNIT_ROUNDOFF * smallest {
            break;
        }
        let newton = lambda - f / derivative;
        lambda = select(0.5 * (low + high), newton, newton > low && newton < high);
    }
    var result: Touch;
    let surface = squared * p / (squared + vec3<f32>(lambda));
    let on = dot(surface / a, surface / a);
    if finite3(surface) && abs(on - 1.0) < 1e-4 && dot(surface, surface) > 0.0 {
        result.surface = surface;
    } else {
        let direction = select(vec3<f32>(0.0, 1.0, 0.0), normalize(p), dot(p, p) > 0.0);
        result.surface = direction / length(direction / a);
    }
    result.normal = normalize(result.surface / squared);
    result.distance = dot(p - result.surface, result.normal);
    return result;
}

// Where `local` (collider `c`'s frame) meets its surface grown by `thickness`: radially for a sphere, from
// the axis for a capsule, the closest point for an ellipsoid, straight up for a plane; for a box, from its
// nearest point outside it and through the nearest face inside; for a mesh, Newton steps along the field's
// gradient to its zero level, `p ← p − d ∇d / |∇d|²`.
fn touch_local(c: u32, local: vec3<f32>, thickness: f32, gap: f32) -> Touch {
    var result: Touch;
    result.distance = distance_bound(c, local, thickness);
    result.surface = local;
    result.normal = vec3<f32>(0.0, 1.0, 0.0);
    if result.distance >= gap {
        return result;
    }
    let shape = collider_row(c, 4u);
    let kind = u32(shape.w);
    switch kind {
        case 0u, 1u: {
            let radius = shape.x + thickness;
            let axis = vec3<f32>(0.0, clamp(local.y, -shape.y, shape.y), 0.0);
            let away = local - axis;
            let r = length(away);
            if r > 0.0 {
                result.normal = away / r;
            } else if kind == 1u {
                result.normal = vec3<f32>(1.0, 0.0, 0.0);
            }
            result.surface = axis + result.normal * radius;
        }
        case 2u: {
            result = closest_on_ellipsoid(shape.xyz + vec3<f32>(thickness), local);
        }
        case 3u: {
            result.surface = vec3<f32>(local.x, thickness, local.z);
        }
        case 4u: {
            let h = shape.xyz;
            let rounding = collider_row(c, 5u).x + thickness;
            let nearest = clamp(local, -h, h);
            let away = local - nearest;
            if dot(away, away) > 0.0 {
                result.normal = normalize(away);
                result.surface = nearest + rounding * result.normal;
            } else {
                let q = abs(local) - h;
                var axis = 2u;
                if q.x >= q.y && q.x >= q.z {
                    axis = 0u;
                } else if q.y >= q.z {
                    axis = 1u;
                }
                var n = vec3<f32>(0.0);
                n[axis] = select(1.0, -1.0, local[axis] < 0.0);
                var surface = local;
                surface[axis] = n[axis] * (h[axis] + rounding);
                result.normal = n;
                result.surface = surface;
            }
            result.distance = dot(local - result.surface, result.normal);
        }
        default: {
            let grown = collider_row(c, 5u).x + thickness;
            var surface = local;
            for (var k = 0u; k < 8u; k++) {
                let field = mesh_distance(c, surface, grown);
                let squared = dot(field.yzw, field.yzw);
                if abs(field.x) <= MOVE_MARGIN * UNIT_ROUNDOFF * length(surface) || squared < 1e-12 {
                    break;
                }
                surface -= field.yzw * (field.x / squared);
            }
            let gradient = mesh_distance(c, surface, grown).yzw;
            result.normal = select(vec3<f32>(0.0, 1.0, 0.0), normalize(gradient), dot(gradient, gradient) > 0.0);
            result.surface = surface;
        }
    }
    return result;
}

// The signed distance of `p` (head-relative) from collider `c` at its end pose grown by `thickness`, the
// closest surface point and the outward normal (head-relative), as `touch_local` finds them.
fn touch(c: u32, p: vec3<f32>, thickness: f32, gap: f32) -> Touch {
    let centre = collider_row(c, 2u).xyz;
    let rotation = collider_row(c, 3u);
    var result = touch_local(c, inverse_rotate(rotation, p - centre), thickness, gap);
    result.surface = centre + rotate(rotation, result.surface);
    result.normal = rotate(rotation, result.normal);
    return result;
}

// The fraction along `start`–`end` of its point closest to the origin.
fn closest_to_origin(start: vec3<f32>, end: vec3<f32>) -> f32 {
    let path = end - start;
    let squared = dot(path, path);
    return select(0.0, clamp(-dot(start, path) / squared, 0.0, 1.0), squared > 0.0);
}

// The fraction along `start`–`end` of its point closest to the axis segment `(0, ±half_length, 0)`: the
// closest points of two segments (Ericson, *Real-Time Collision Detection*, 5.1.9).
fn closest_to_axis(start: vec3<f32>, end: vec3<f32>, half_length: f32) -> f32 {
    let path = end - start;
    let axis = vec3<f32>(0.0, 2.0 * half_length, 0.0);
    let offset = start + 0.5 * axis;
    let a = dot(path, path);
    let e = dot(axis, axis);
    let f = dot(axis, offset);
    let c = dot(path, offset);
    if a == 0.0 {
        return 0.0;
    }
    if e == 0.0 {
        return clamp(-c / a, 0.0, 1.0);
    }
    let b = dot(path, axis);
    let denominator = a * e - b * b;
    let s = select(0.0, clamp((b * f - c * e) / denominator, 0.0, 1.0), denominator > 0.0);
    let t = (b * s + f) / e;
    if t < 0.0 {
        return clamp(-c / a, 0.0, 1.0);
    }
    if t > 1.0 {
        return clamp((b - c) / a, 0.0, 1.0);
    }
    return s;
}

// The fraction between `low` and `high` along `start`–`end` of its point deepest in collider `c` (grown by
// `thickness`), and the distance there: a golden-section search of `iterations` steps, the ends included
// (exact where the distance is convex along the segment: a convex solid).
fn deepest_between(c: u32, start: vec3<f32>, end: vec3<f32>, low_in: f32, high_in: f32, iterations: u32, thickness: f32) -> vec2<f32> {
    let golden = 0.618034;
    var low = low_in;
    var high = high_in;
    var a = high - golden * (high - low);
    var b = low + golden * (high - low);
    var at_a = distance_bound(c, mix(start, end, a), thickness);
    var at_b = distance_bound(c, mix(start, end, b), thickness);
    for (var k = 0u; k < iterations; k++) {
        if at_a <= at_b {
            high = b;
            b = a;
            at_b = at_a;
            a = high - golden * (high - low);
            at_a = distance_bound(c, mix(start, end, a), thickness);
        } else {
            low = a;
            a = b;
            at_a = at_b;
            b = low + golden * (high - low);
            at_b = distance_bound(c, mix(start, end, b), thickness);
        }
    }
    var best = vec2<f32>(0.5 * (low + high), distance_bound(c, mix(start, end, 0.5 * (low + high)), thickness));
    let first = distance_bound(c, mix(start, end, low_in), thickness);
    if first < best.y {
        best = vec2<f32>(low_in, first);
    }
    let last = distance_bound(c, mix(start, end, high_in), thickness);
    if last < best.y {
        best = vec2<f32>(high_in, last);
    }
    return best;
}

// The push (head-relative) that moves the point of the edge `start`–`end` (head-relative) deepest inside
// collider `c` (grown by `thickness`, at its end pose) out to its surface, and that point's fraction along
// the edge; a fraction below 0 when the edge does not dip in (`segment_contact` on the CPU).
fn edge_push(c: u32, start_in: vec3<f32>, end_in: vec3<f32>, thickness: f32) -> vec4<f32> {
    let none = vec4<f32>(0.0, 0.0, 0.0, -1.0);
    let centre = collider_row(c, 2u).xyz;
    let rotation = collider_row(c, 3u);
    let start = inverse_rotate(rotation, start_in - centre);
    let end = inverse_rotate(rotation, end_in - centre);
    let length_along = length(end - start);
    if distance_bound(c, start, thickness) > length_along {
        return none;
    }
    let shape = collider_row(c, 4u);
    var fraction = 0.0;
    switch u32(shape.w) {
        case 0u: {
            fraction = closest_to_origin(start, end);
        }
        case 1u: {
            fraction = closest_to_axis(start, end, shape.y);
        }
        case 2u: {
            let axes = shape.xyz + vec3<f32>(thickness);
            fraction = closest_to_origin(start / axes, end / axes);
        }
        case 3u: {
            // A segment only dips below a plane at an end.
            return none;
        }
        case 4u: {
            fraction = deepest_between(c, start, end, 0.0, 1.0, 32u, thickness).x;
        }
        default: {
            // Not convex: the deepest of the stretches, at most half a cell of the field long, that can
            // reach inside (a stretch whose ends lie `d₀` and `d₁` out stays outside if `d₀ + d₁` exceeds
            // its length; a margin for the interpolation, whose slope may exceed one slightly).
            let least = min(shape.x, min(shape.y, shape.z));
            let spacing = 0.5 * collider_row(c, 5u).y * least;
            let intervals = u32(clamp(ceil(length_along / spacing), 1.0, 64.0));
            let stretch = length_along / f32(intervals);
            var deepest = vec2<f32>(0.0, 1e30);
            var before = distance_bound(c, start, thickness);
            for (var k = 0u; k < intervals; k++) {
                let low = f32(k) / f32(intervals);
                let high = f32(k + 1u) / f32(intervals);
                let after = distance_bound(c, mix(start, end, high), thickness);
                if before + after <= 1.1 * stretch {
                    let found = deepest_between(c, start, end, low, high, 20u, thickness);
                    if found.y < deepest.y {
                        deepest = found;
                    }
                }
                before = after;
            }
            fraction = deepest.x;
        }
    }
    let point = mix(start, end, fraction);
    let met = touch_local(c, point, thickness, 0.0);
    if met.distance >= 0.0 {
        return none;
    }
    return vec4<f32>(rotate(rotation, met.surface - point), fraction);
}

// Where collider `c`'s body carries the point that was at `p` (head-relative) at the step's start: from
// its start pose to its end pose.
fn carried_by(c: u32, p: vec3<f32>) -> vec3<f32> {
    let local = inverse_rotate(collider_row(c, 1u), p - collider_row(c, 0u).xyz);
    return collider_row(c, 2u).xyz + rotate(collider_row(c, 3u), local);
}

// The velocity of collider `c`'s body over the step at the point that was at `p` at its start.
fn collider_velocity(c: u32, p: vec3<f32>) -> vec3<f32> {
    return (carried_by(c, p) - p) / params.dt;
}

// This lane's node, where inside a collider, put on its surface; with `friction`, its slip over the step
// relative to the collider (from where the node was at the start, in the collider's start frame) is
// cancelled up to μ times the push (Macklin et al. 2014). Then the edges that dip into a collider between
// their nodes are pushed out at their deepest point (`push_edges`). Returns whether any lane's node moved.
fn push_out(friction: bool) -> bool {
    let first_collider = bitcast<u32>(head_row(3u).x);
    let count = bitcast<u32>(head_row(3u).y);
    let thickness = strand_floats[strand * STRAND_FLOATS + 1u].w;
    var moved = false;
    for (var k = 0u; k < count; k++) {
        let c = first_collider + k;
        if !meets(c, thickness) {
            continue;
        }
        let contact = touch(c, x, thickness, 0.0);
        if contact.distance >= 0.0 {
            continue;
        }
        var goal = contact.surface;
        if friction {
            let mu = collider_row(c, 2u).w;
            // Where the node started, carried with the collider to its end pose.
            let slip = goal - carried_by(c, x_start);
            let tangential = slip - dot(slip, contact.normal) * contact.normal;
            // The normal push this step: the spring's force in the solve (as a displacement over the
            // step, `k d h² / m = CONTACT_RATIO d`) and the push-out itself.
            let limit = mu * -contact.distance * (1.0 + CONTACT_RATIO * spring);
            let size = length(tangential);
            if size <= limit {
                goal -= tangential;
            } else {
                goal -= tangential * (limit / size);
            }
            // Back onto the surface after the friction's tangential move.
            let again = touch(c, goal, thickness, 0.0);
            if again.distance < 0.0 {
                goal = again.surface;
            }
        }
        // Moved only by more than the position's rounding: a node left on the surface to within rounding
        // ends the rounds.
        let shift = length(goal - x);
        moved = moved || shift > MOVE_MARGIN * UNIT_ROUNDOFF * length(x);
        x = goal;
        normal = contact.normal;
        pushed = true;
        surface_speed = dot(collider_velocity(c, x_start), normal);
    }
    publish_nodes();
    moved = push_edges(thickness) || moved;
    return largest_over_lanes(select(0.0, 1.0, moved)) > 0.0;
}

// The edges between free nodes that dip into a collider between their nodes (a strand lying across a box's
// edge, a chord of a curved surface), each pushed out at its deepest point, the push shared by its two
// nodes by their inverse masses and their distance from that point, as on the CPU (`push_out` in
// `rod/contact.rs`); edges shorter than `√(8 ρ thickness)` (ρ the collider's least radius of curvature)
// cannot dip in without a node touching, and are not tested. Unlike the CPU:
// - every edge is tested where the nodes are (Jacobi), and a node pushed by both its edges moves by the
//   mean of their pushes: edge after edge (Gauss–Seidel), each would find less to push than the last;
// - each node moves along the collider's normal at itself, as far as brings the deepest point out along
//   the push: along the push itself, the nodes at the ends of a contact would move a little along the
//   surface each step, and slide resting hair off it;
// - a node lifted off the surface so has its height kept for the next step's contact spring
//   (`add_contact_springs`), and its speed away from the surface taken off (contact is inelastic).
// A node's push from the edge after it passes through `shared_t` (free during contact), with the collider
// that pushed it. Returns whether this lane's node moved by more than its rounding.
fn push_edges(thickness: f32) -> bool {
    let first_collider = bitcast<u32>(head_row(3u).x);
    let count = bitcast<u32>(head_row(3u).y);
    // Edge `lane` from node `lane` to node `node`; both free (not the root edge's, not held; every edge of a
    // free strand).
    let start_arc = arc - rest_at(lane, 0u).x;
    var start_push = vec3<f32>(0.0);
    var end_push = vec3<f32>(0.0);
    var pushed_by = 0.0;
    if own_edge && (lane >= 2u || free) {
        let start = shared_x[lane].xyz;
        let end = x;
        let start_weight = node_inverse_mass(lane);
        let end_weight = node_inverse_mass(node);
        for (var k = 0u; k < count; k++) {
            let c = first_collider + k;
            let shortest = 8.0 * collider_row(c, 5u).w * thickness;
            let d = end - start;
            if (!free && start_arc <= held_reach(c, thickness)) || dot(d, d) <= shortest {
                continue;
            }
            let found = edge_push(c, start + start_push, end + end_push, thickness);
            let f = found.w;
            if f < 0.0 {
                continue;
            }
            let start_share = (1.0 - f) * start_weight;
            let end_share = f * end_weight;
            let scale = (1.0 - f) * start_share + f * end_share;
            if scale <= 0.0 {
                continue;
            }
            // Each node moves along the collider's normal at itself, as far as brings the deepest point out
            // along the push: a push along the edge's own normal would move the nodes at the ends of a
            // contact a little along the surface each step, and slide resting hair off it.
            let size = length(found.xyz);
            let direction = found.xyz / size;
            let start_normal = touch(c, start + start_push, thickness, 1e30).normal;
            let end_normal = touch(c, end + end_push, thickness, 1e30).normal;
            start_push += start_share / scale * size / max(dot(start_normal, direction), 0.5) * start_normal;
            end_push += end_share / scale * size / max(dot(end_normal, direction), 0.5) * end_normal;
            pushed_by = f32(c + 1u);
        }
    }
    workgroupBarrier();
    if own_edge {
        shared_t[lane] = vec4<f32>(start_push, pushed_by);
    }
    workgroupBarrier();
    var moved = false;
    if own_node {
        var push = end_push;
        var pushes = select(0.0, 1.0, pushed_by > 0.0);
        var by = pushed_by;
        if node < edge_count() && shared_t[node].w > 0.0 {
            push += shared_t[node].xyz;
            pushes += 1.0;
            by = max(by, shared_t[node].w);
        }
        if pushes > 0.0 {
            let shift = push / pushes;
            let size = length(shift);
            moved = size > MOVE_MARGIN * UNIT_ROUNDOFF * length(x);
            x += shift;
            if size > 0.0 {
                normal = shift / size;
                pushed = true;
                lifted = true;
                lifted_by = u32(by) - 1u;
                surface_speed = dot(collider_velocity(u32(by) - 1u, x_start), normal);
            }
        }
    }
    publish_nodes();
    return moved;
}

// This lane's node and edge back in the rest pose the strand was uploaded in, carried with its head.
fn reset_to_rest() {
    if own_node {
        x = rotate(head_row(0u), rest_at(node, 2u).xyz);
        x_hat = x;
    }
    if own_edge {
        let pose = rest_at(lane, 2u);
        let frame = rest_at(lane, 3u);
        theta = pose.w;
        director = rotate(head_row(0u), frame.xyz);
        reference_twist = frame.w;
        theta_start = theta;
    }
    if holds_root {
        root_x = rotate(head_row(0u), rest_at(0u, 2u).xyz);
        root_hat = root_x;
    }
    publish_nodes();
}

// `v` (head-relative, at the head's last pose) turned with the head to its pose now.
fn turned_with_head(v: vec3<f32>) -> vec3<f32> {
    return rotate(head_row(0u), inverse_rotate(head_row(4u), v));
}

// A strand whose head is carried this fixed step: moved rigidly with its head from the head's pose at the
// last fixed step to its pose now, its twists unchanged, its history dropped (its next step is backward
// Euler, as after an upload). Out of sight, its velocity becomes the head's rigid motion (it comes back with
// its head's motion); waiting for its next step at a coarser level, its velocity turns with the head and
// is kept, so that the next step, as long as the fixed steps it spans, goes on with the hair's own motion
// (a still head's hair then steps exactly as the CPU's does at that level). `shift` is the head's
// translation before less after.
fn carry_with_head(shift: vec3<f32>, keep_motion: bool) {
    var moved = vec3<f32>(0.0);
    var velocity = vec3<f32>(0.0);
    if own_edge {
        let p = state[state_index(node, 0u)].xyz;
        moved = turned_with_head(p);
        velocity = (moved - (p + shift)) / params.dt;
        if keep_motion {
            velocity = turned_with_head(state[state_index(node, 1u)].xyz);
        }
        shared_x[node] = vec4<f32>(moved, 0.0);
        shared_m[node] = vec4<f32>(velocity, 0.0);
    }
    if lane == 0u {
        let p = state[state_index(0u, 0u)].xyz;
        let root = turned_with_head(p);
        shared_x[0] = vec4<f32>(root, 0.0);
        var root_velocity = (root - (p + shift)) / params.dt;
        if keep_motion {
            root_velocity = turned_with_head(state[state_index(0u, 1u)].xyz);
        }
        shared_m[0] = vec4<f32>(root_velocity, 0.0);
    }
    workgroupBarrier();
    // Row `k` of node `lane` by lane `lane` (the last node's by the last lane), as at a step's end.
    if own_edge {
        let edge_row = state[state_index(lane, 0u)];
        let frame = state[state_index(lane, 4u)];
        state[state_index(lane, 0u)] = vec4<f32>(shared_x[lane].xyz, edge_row.w);
        let rate = select(0.0, state[state_index(lane, 1u)].w, keep_motion);
        state[state_index(lane, 1u)] = vec4<f32>(shared_m[lane].xyz, rate);
        state[state_index(lane, 4u)] = vec4<f32>(turned_with_head(frame.xyz), frame.w);
        state[state_index(node, 3u)] = vec4<f32>(velocity, 0.0);
        if node == edge_count() {
            state[state_index(node, 0u)] = vec4<f32>(moved, 0.0);
            state[state_index(node, 1u)] = vec4<f32>(velocity, 0.0);
        }
    }
    if lane == 0u {
        // No history, no fault, no contact: the failed steps' count and the last one's reason are kept.
        let before_status = status[strand];
        status[strand] = vec4<u32>(0u, before_status.y, before_status.z, before_status.w);
    }
}

@compute @workgroup_size(LANES)
fn step(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let listed = group.x + group.y * groups.x;
    lane = local;
    if listed >= params.list_length {
        return;
    }
    // The strands by the lanes they need (in `strand_words[k].w`: those of up to 32 edges, then the longer
    // ones, each list one dispatch).
    strand = strand_words[params.list_start + listed].w;
    let words = strand_words[strand * STRAND_WORDS];
    nodes = words.x;
    head = words.y & HEAD_INDEX;
    free = (words.y & FREE_STRAND) != 0u;
    first = words.z;
    // (A free strand needs a lane per node, one more than a held one.)
    if nodes < 3u || nodes > select(MAX_NODES, LANES, free) {
        return;
    }
    own_edge = lane + 1u < nodes;
    node = select(lane + 1u, 0u, free && lane + 1u == nodes);
    own_node = own_edge || (free && lane + 1u == nodes);
    holds_root = lane == 0u && !free;
    // This lane's entries of the factorisation's trailing update: the `lane`th and `lane + LANES`th of the
    // triangle below a pivot, row by row.
    for (var k = 0u; k < 2u; k++) {
        let entry = lane + k * LANES;
        update_rows[k] = 0u;
        update_columns[k] = 0u;
        if entry < UPDATE_ENTRIES {
            var row = 1u;
            var before = 0u;
            while before + row <= entry {
                before += row;
                row++;
            }
            update_rows[k] = row;
            update_columns[k] = entry - before + 1u;
        }
    }
    if lane == 0u {
        atomicStore(&reduced, 0u);
    }
    var flags = status[strand].x & STATUS_FLAGS;
    if params.restart != 0u {
        flags = flags & ~HAS_HISTORY;
    }
    let shift = head_row(1u).xyz;
    // The fixed steps this step spans (a coarser level of detail steps every `n`-th fixed step with a
    // step `n` times as long); 0: the head is carried this fixed step, its hair with it.
    let span = bitcast<u32>(head_row(5u).w);
    if span == CARRIED || span == WAITING {
        carry_with_head(shift, span == WAITING);
        return;
    }
    // A step longer than the last one has no history it can use (BDF2's is for equal steps).
    let last_span = (status[strand].x >> SPAN_SHIFT) & 0xffu;
    if span != max(last_span, 1u) {
        flags = flags & ~HAS_HISTORY;
    }
    step_dt = params.dt * f32(span);
    let dt = step_dt;
    let two_step = params.bdf2 != 0u && (flags & HAS_HISTORY) != 0u;
    let h = select(dt, 2.0 / 3.0 * dt, two_step);

    // 1. Load, shift to the head's new translation; the scheme's prediction. Row `k` of node `i` holds
    // node `i`'s and edge `i`'s values: this lane's edge is at `lane`, its node at `node`.
    if own_edge {
        let edge_row = state[state_index(lane, 0u)];
        theta = edge_row.w;
        theta_start = edge_row.w;
        theta_rate = state[state_index(lane, 1u)].w;
        let frame = state[state_index(lane, 4u)];
        director = frame.xyz;
        reference_twist = frame.w;
    }
    if own_node {
        let p = state[state_index(node, 0u)];
        let v = state[state_index(node, 1u)];
        x = p.xyz + shift;
        x_start = x;
        normal = vec3<f32>(0.0);
        pushed = false;
        lifted = false;
        lifted_before = select(0.0, state[state_index(node, 3u)].w, two_step);
        if two_step {
            let before = state[state_index(node, 2u)].xyz + shift;
            let v_before = state[state_index(node, 3u)].xyz;
            x_hat = (4.0 * x - before) / 3.0;
            v_hat = (4.0 * v.xyz - v_before) / 3.0;
        } else {
            x_hat = x;
            v_hat = v.xyz;
        }
        v_start = v.xyz;
        // Consumed: each step's forces and added air velocities are written for it.
        node_air = air_at(x_start) + state[state_index(node, 6u)].xyz;
        state[state_index(node, 6u)] = vec4<f32>(0.0);
        node_force = state[state_index(node, 5u)].xyz;
        state[state_index(node, 5u)] = vec4<f32>(0.0);
        // The arc length of rest lengths from the root to this node.
        arc = 0.0;
        for (var e = 0u; e < node; e++) {
            arc += rest_at(e, 0u).x;
        }
    }
    if holds_root {
        root_x = state[state_index(0u, 0u)].xyz + shift;
        root_hat = root_x;
        if two_step {
            root_hat = (4.0 * root_x - (state[state_index(0u, 2u)].xyz + shift)) / 3.0;
        }
        // The history this step leaves: the root's position and velocity at its start.
        state[state_index(0u, 2u)] = vec4<f32>(root_x, 0.0);
        state[state_index(0u, 3u)] = vec4<f32>(state[state_index(0u, 1u)].xyz, 0.0);
    }
    publish_nodes();
    if own_node {
        // The node's tangent at the step's start (for the drag): the mean of its edges'.
        let i = node;
        if i == 0u {
            start_tangent = normalize(shared_x[1].xyz - x);
        } else {
            let before = normalize(x - shared_x[i - 1u].xyz);
            if i == edge_count() {
                start_tangent = before;
            } else {
                let after = normalize(shared_x[i + 1u].xyz - x);
                let sum = before + after;
                start_tangent = select(after, normalize(sum), dot(sum, sum) > 1e-12);
            }
        }
        // The history this step leaves: positions and velocities at its start.
        state[state_index(i, 2u)] = vec4<f32>(x_start, 0.0);
        state[state_index(i, 3u)] = vec4<f32>(v_start, 0.0);
    }
    if own_edge {
        tangent = normalize(x - shared_x[lane].xyz);
    }

    // 2. The first guess: carried with the root (a free strand's is where it is).
    if !free {
        carry_with_root();
    }
    x_carried = x;
    theta_carried = theta;
    root_carried = root_x;

    // 3. Newton iterations.
    var fault = 0u;
    var fault_at = 0u;
    let target_tangent = normalize(root_target(1u) - root_target(0u));
    // A longer step (a coarser level of detail) is further from linear: one more Newton iteration for each
    // fixed step it spans past the first, which its level still pays less for than for every fixed step.
    let newton_iterations = params.newton_iterations + span - 1u;
    for (var iteration = 0u; iteration < newton_iterations; iteration++) {
        let offset = select(from_lane_zero(root_twist_offset(target_tangent, root_target(2u))), 0.0, free);
        if !assemble_and_factorize(iteration, h, offset) {
            fault = FAULT_NOT_DEFINITE;
            break;
        }
        workgroupBarrier();
        for (var k = lane; k < dofs(); k += LANES) {
            rhs[k] = -rhs[k];
        }
        solve();
        // The trust region: no edge (but a held root's) turns by more than `max_rotation`.
        var turn = 0.0;
        if (lane >= 1u || free) && own_edge {
            let e = lane;
            let d = shared_x[e + 1u].xyz - shared_x[e].xyz;
            let change = vec3<f32>(rhs[4u * e + 4u], rhs[4u * e + 5u], rhs[4u * e + 6u])
                - vec3<f32>(rhs[4u * e], rhs[4u * e + 1u], rhs[4u * e + 2u]);
            let along = dot(change, d) / dot(d, d);
            turn = length(change - along * d) / length(d) + max(-along - 0.5, 0.0);
        }
        let largest = largest_over_lanes(turn);
        if !finite(largest) {
            fault = FAULT_NON_FINITE;
            break;
        }
        let fraction = select(1.0, params.max_rotation / largest, largest > params.max_rotation);
        if own_node {
            x += fraction * vec3<f32>(rhs[4u * node], rhs[4u * node + 1u], rhs[4u * node + 2u]);
        }
        if own_edge {
            theta += fraction * rhs[4u * lane + 3u];
        }
        if holds_root {
            root_x += fraction * vec3<f32>(rhs[0], rhs[1], rhs[2]);
        }
        work_steps.y += 1u;
        let last = iteration + 1u == newton_iterations;
        if last && holds_root {
            // Exactly on the root's targets.
            root_x = root_target(0u);
            x = root_target(1u);
            theta += root_twist_offset(target_tangent, root_target(2u));
        }
        publish_nodes();
        // Before another iteration the lengths need only be near enough for its linearisation (its solve
        // has no stretching force): one projection iteration, which takes the update's second-order
        // stretch (½ turn², up to 5e-3) to ~1e-5. After the last, as exact as single precision resolves.
        // (No projection before another iteration saves 0.4 iterations a strand-step on the shaken head
        // but leaves a held strand 7 % further from the CPU's: `tests/gpu/step.rs`.)
        project_lengths(select(1u, projection_limit(), last));

        refresh_frames();
    }

    // 4. Contact with the head's colliders. A strand that cannot be put outside them with its lengths kept
    // (one deep inside a collider that holds its root, say) keeps its solved state for this step instead
    // (status bit `CONTACT_GIVEN_UP`): it stays whole and comes out as far as it can in later steps.
    flags = flags & ~CONTACT_GIVEN_UP;
    if fault == 0u && bitcast<u32>(head_row(3u).y) > 0u {
        x_carried = x;
        for (var round = 0u; round < params.contact_rounds; round++) {
            work_more.x += 1u;
            if !push_out(round == 0u) {
                break;
            }
            project_lengths(projection_limit());
        }
        let strained = largest_strain().x;
        if !(strained <= params.strain_bound) {
            x = x_carried;
            normal = vec3<f32>(0.0);
            pushed = false;
            lifted = false;
            flags = flags | CONTACT_GIVEN_UP;
            publish_nodes();
        }
        refresh_frames();
    }

    // 5. Checks.
    var strain = largest_strain();
    if fault == 0u {
        // The first node whose position, or whose edge's θ, is not finite.
        var mine = 0xffffffffu;
        if own_node && !finite3(x) {
            mine = node;
        }
        if own_edge && !finite(theta) {
            mine = min(mine, lane);
        }
        if holds_root && !finite3(root_x) {
            mine = 0u;
        }
        let at = smallest_over_lanes(mine);
        if at != 0xffffffffu {
            fault = FAULT_NON_FINITE;
            fault_at = at;
        }
    }
    if fault == 0u && (!finite(strain.x) || strain.x > params.strain_bound) {
        fault = FAULT_OVER_STRAINED;
        fault_at = u32(strain.y);
    }
    // On a failed step, the strain reported is the one that failed it.
    let failing_strain = strain.x;
    if fault != 0u {
        reset_to_rest();
        flags = flags & ~HAS_HISTORY;
        strain = largest_strain();
    } else {
        flags = flags | HAS_HISTORY;
    }

    // The nodes touching a collider after the step: held by a contact spring in the solve or moved by the
    // contact after it (`HairStatistics::contacts` on the CPU).
    let contacts = count_over_lanes(own_node && fault == 0u && (spring > 0.0 || pushed));

    // 6. Velocities and the state written back: each node's velocity shared (in `shared_m`), then row `k`
    // of node `lane` (its position and velocity beside edge `lane`'s θ and θ̇) by lane `lane`, the last
    // node's by the last lane.
    let stopped = fault != 0u;
    publish_nodes();
    var v = select((x - x_hat) / h, vec3<f32>(0.0), stopped);
    // Contact is inelastic: a node the contact moved keeps no speed away from the surface beyond the
    // surface's own (the push that put it outside is not a velocity it flies off with, to fall back and be
    // pushed out again the next step: hair resting on a collider would never rest).
    if pushed {
        let away = dot(v, normal) - surface_speed;
        if away > 0.0 {
            v -= away * normal;
        }
    }
    if own_node {
        shared_m[node] = vec4<f32>(v, 0.0);
    }
    if holds_root {
        shared_m[0] = vec4<f32>(select((root_x - root_hat) / h, vec3<f32>(0.0), stopped), 0.0);
    }
    workgroupBarrier();
    if own_edge {
        let rate = select((theta - theta_start) / dt, 0.0, stopped);
        state[state_index(lane, 0u)] = vec4<f32>(shared_x[lane].xyz, theta);
        state[state_index(lane, 1u)] = vec4<f32>(shared_m[lane].xyz, rate);
        state[state_index(lane, 4u)] = vec4<f32>(director, reference_twist);
    }
    if own_node {
        // The history row, with how far above the surface an edge's push left the node (for the next
        // step's springs).
        var height = 0.0;
        if lifted && !stopped {
            let thickness = strand_floats[strand * STRAND_FLOATS + 1u].w;
            height = max(touch(lifted_by, x, thickness, 1e30).distance, 0.0);
        }
        state[state_index(node, 3u)] = vec4<f32>(v_start, height);
        if node == edge_count() {
            state[state_index(node, 0u)] = vec4<f32>(x, 0.0);
            state[state_index(node, 1u)] = vec4<f32>(v, 0.0);
        }
    }
    if lane == 0u {
        // The failed steps' count keeps the last one's reason in its top bits, and `y` where it was, so
        // that a read-back every few steps still says why.
        let before = status[strand];
        var failures = before.w;
        var at = before.y;
        if stopped {
            failures = (((failures & FAULT_COUNT) + 1u) & FAULT_COUNT) | (fault << 28u);
            at = fault_at;
        }
        let reported = select(strain.x, failing_strain, fault == FAULT_OVER_STRAINED);
        let kept = (flags & (HAS_HISTORY | CONTACT_GIVEN_UP)) | fault | (span << SPAN_SHIFT);
        status[strand] = vec4<u32>(kept | (contacts << CONTACTS_SHIFT), at, bitcast<u32>(reported), failures);
        work_steps.x = 1u;
        let row = strand * WORK_ROWS;
        work[row] = work[row] + work_steps;
        work[row + 1u] = work[row + 1u] + work_more;
    }
}
