// One implicit step of discrete elastic rods (Bergou et al. 2008) per strand, in single precision: the
// CPU's step (`src/rod/solver.rs`) with inextensibility by projection instead of a stiff stretching term
// in the solve (see `src/gpu/mod.rs` for why, and for what differs).
//
// One invocation per strand. Buffers are vertex-major: entry `k` of node `i` of strand `s` is at
// `(i * K + k) * strands + s`, so that neighbouring invocations read neighbouring memory. Positions are
// relative to the strand's head (its translation at the end of the last step), so that single precision
// resolves micrometres wherever the head is. Each step:
//   1. shift to the head's new translation; carry the strand rigidly with its root's motion (first guess);
//   2. BDF2's prediction (`x̂ = (4xₙ − xₙ₋₁)/3`, `v̂` alike, `h = ⅔ dt`), backward Euler on the first step;
//   3. Newton iterations on `(M/h² + D/h + (1 + β/dt) H) Δq = −[M (q − x̂ − h v̂)/h² + D ((q − x̂)/h − u)
//      + ∇E + β/dt H (q − q̃) − M g]` over `(x₀, θ⁰, x₁, …)`, the root edge prescribed, solved by a banded
//      `L D Lᵀ` (half-bandwidth 10) in private memory, each update within a trust region and the frames
//      carried (time-parallel transport), each followed by a projection onto the edges' rest lengths
//      (Goldenthal et al. 2007): one iteration between Newton iterations, after the last until single
//      precision resolves no better;
//   4. contact: nodes inside a collider (at its end pose, grown by the strand's thickness) put on its
//      surface, with Coulomb friction against their slip over the step relative to the collider, then the
//      lengths again, touching nodes moving only along their surfaces, until no node moves by more than
//      its position's rounding;
//   5. checks: a strand with a non-finite value or an edge strained past the bound is put back in its rest
//      pose on its root, at rest, and its status says why;
//   6. velocities `v = (x − x̂)/h`, twist rates by backward Euler, and the history for the next step.

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
    unused_0: u32,
    unused_1: u32,
    unused_2: u32,
}

// Per strand words: node count, head, 0, 0.
const STRAND_WORDS: u32 = 1u;
// Per strand floats: (EA, EI₁, EI₂, GJ); (root node 0 head-local, thickness); (root node 1, 0);
// (root material direction, 0).
const STRAND_FLOATS: u32 = 4u;
// Rest data per node: (rest length of edge i, Voronoi length of vertex i, κ̄₁, κ̄₂), (τ̄, mass, twist
// inertia of edge i, 0), (rest pose node, θ), (rest pose reference director, reference twist), (the node's
// groomed place for the style hold, head-local; its arc length from the root over the strand's, past 1
// where the strand is not held).
const REST_ROWS: u32 = 5u;
// State per node: (position, θ of edge i), (velocity, θ̇), (position a step back, 0), (velocity a step
// back, 0), (reference director of edge i, reference twist at vertex i).
const STATE_ROWS: u32 = 5u;
// Per head: (rotation at the step's end), (shift of the origin: translation before − after, 0), (the air's
// velocity, 0), (first collider, colliders as bits, the style hold's rate in 1/s and its reach), (rotation
// at the step's start).
const HEAD_ROWS: u32 = 5u;
// Per collider: (centre at the start, relative to its head's new translation; bounding radius),
// (rotation at the start), (centre at the end; friction), (rotation at the end), (shape: sphere
// (r, 0, 0, 0), capsule (r, half length, 0, 1), ellipsoid (semi-axes, 2), plane (0, 0, 0, 3)).
const COLLIDER_ROWS: u32 = 5u;

const MAX_NODES: u32 = 40u;
const MAX_DOFS: u32 = 159u;
const BAND: u32 = 10u;
const WIDTH: u32 = 11u;
// Invocations per workgroup (`STEP_WORKGROUP` in `solver.rs`).
const WORKGROUP: u32 = 32u;

// Status bits (per strand, `status[s].x`): has a step of history; the last step was faulted (non-finite,
// over-strained, not definite) or its contact given up, with the node or edge of the last fault in
// `status[s].y`, `status[s].z`
// the largest strain as bits, `status[s].w` the failed steps and the last one's reason.
const HAS_HISTORY: u32 = 1u;
const FAULT_NON_FINITE: u32 = 2u;
const FAULT_OVER_STRAINED: u32 = 4u;
const FAULT_NOT_DEFINITE: u32 = 8u;
const CONTACT_GIVEN_UP: u32 = 16u;
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

// The strand's working copy.
var<private> x: array<vec3<f32>, MAX_NODES>;
var<private> theta: array<f32, MAX_NODES>;
var<private> x_start: array<vec3<f32>, MAX_NODES>;
var<private> theta_start: array<f32, MAX_NODES>;
var<private> theta_rate: array<f32, MAX_NODES>;
var<private> x_hat: array<vec3<f32>, MAX_NODES>;
var<private> v_hat: array<vec3<f32>, MAX_NODES>;
var<private> x_carried: array<vec3<f32>, MAX_NODES>;
var<private> theta_carried: array<f32, MAX_NODES>;
var<private> director: array<vec3<f32>, MAX_NODES>;
var<private> tangent: array<vec3<f32>, MAX_NODES>;
var<private> reference_twist: array<f32, MAX_NODES>;
var<private> m1: array<vec3<f32>, MAX_NODES>;
var<private> m2: array<vec3<f32>, MAX_NODES>;
var<private> inverse_length: array<f32, MAX_NODES>;
var<private> normal: array<vec3<f32>, MAX_NODES>;
var<private> band: array<f32, 1749>;
var<private> rhs: array<f32, MAX_DOFS>;
var<private> product: array<f32, MAX_DOFS>;
var<private> grad_k1: array<f32, 11>;
var<private> grad_k2: array<f32, 11>;
var<private> grad_tw: array<f32, 11>;
var<private> tri_diagonal: array<f32, MAX_NODES>;
var<private> tri_upper: array<f32, MAX_NODES>;
var<private> tri_rhs: array<f32, MAX_NODES>;
var<private> springs: array<f32, MAX_NODES>;

var<private> strand: u32;
var<private> nodes: u32;
var<private> head: u32;
// This step's work, added to `work` at the end.
var<private> work_steps: vec4<u32>;
var<private> work_more: vec4<u32>;

fn rest_at(node: u32, row: u32) -> vec4<f32> {
    return rest[(node * REST_ROWS + row) * params.strands + strand];
}

fn state_index(node: u32, row: u32) -> u32 {
    return (node * STATE_ROWS + row) * params.strands + strand;
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

fn head_row(row: u32) -> vec4<f32> {
    return heads[head * HEAD_ROWS + row];
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

// Tangents and material directors of every edge from the positions, reference directors and twists.
fn edge_frames() {
    for (var e = 0u; e < edge_count(); e++) {
        let edge = x[e + 1u] - x[e];
        let size = length(edge);
        let t = edge / size;
        tangent[e] = t;
        inverse_length[e] = 1.0 / size;
        let a2 = cross(t, director[e]);
        let c = cos(theta[e]);
        let s = sin(theta[e]);
        m1[e] = c * director[e] + s * a2;
        m2[e] = c * a2 - s * director[e];
    }
}

// Time-parallel transport of each reference director onto its edge's new tangent, then the reference
// twists, each continued from its last value (`Rod::refresh_frames`).
fn refresh_frames() {
    for (var e = 0u; e < edge_count(); e++) {
        let t = normalize(x[e + 1u] - x[e]);
        let carried = transport(director[e], tangent[e], t);
        director[e] = perpendicular_unit(carried, t, any_perpendicular(t));
        tangent[e] = t;
    }
    for (var i = 1u; i < edge_count(); i++) {
        let carried = transport(director[i - 1u], tangent[i - 1u], tangent[i]);
        let angle = signed_angle(carried, director[i], tangent[i]);
        let previous = reference_twist[i];
        reference_twist[i] = previous + wrap_angle(angle - previous);
    }
}

// The change of θ⁰ that turns the root edge's m1 onto the root's material direction.
fn root_twist_offset(target_tangent: vec3<f32>, direction: vec3<f32>) -> f32 {
    let reference = transport(director[0], tangent[0], target_tangent);
    let aim = perpendicular_unit(direction, target_tangent, reference);
    return wrap_angle(signed_angle(reference, aim, target_tangent) - theta[0]);
}

// The strand carried rigidly with its root edge's motion onto the root's targets (`carry_with_first_clamp`).
fn carry_with_root() {
    let p0 = root_target(0u);
    let p1 = root_target(1u);
    let t = normalize(p1 - p0);
    let old_t = tangent[0];
    let a2 = cross(old_t, director[0]);
    let old_m1 = cos(theta[0]) * director[0] + sin(theta[0]) * a2;
    let old_m2 = cross(old_t, old_m1);
    let new_m1 = perpendicular_unit(root_target(2u), t, transport(old_m1, old_t, t));
    let new_m2 = cross(t, new_m1);
    let pivot = x[0];
    for (var i = 0u; i < nodes; i++) {
        let d = x[i] - pivot;
        let local = vec3<f32>(dot(d, old_t), dot(d, old_m1), dot(d, old_m2));
        x[i] = p0 + local.x * t + local.y * new_m1 + local.z * new_m2;
    }
    x[0] = p0;
    x[1] = p1;
    for (var e = 0u; e < edge_count(); e++) {
        let d = director[e];
        let local = vec3<f32>(dot(d, old_t), dot(d, old_m1), dot(d, old_m2));
        director[e] = local.x * t + local.y * new_m1 + local.z * new_m2;
        let g = tangent[e];
        let lg = vec3<f32>(dot(g, old_t), dot(g, old_m1), dot(g, old_m2));
        tangent[e] = lg.x * t + lg.y * new_m1 + lg.z * new_m2;
    }
}

// Bending and twisting at vertex `i`: the curvatures' and twist's gradients over the stencil
// `[x_{i−1}, θ^{i−1}, x_i, θ^i, x_{i+1}]` (Bergou et al. 2008 §7; `vertex_strain` in `energy.rs`).
// Returns (κ₁, κ₂, τ).
fn vertex_strain(i: u32) -> vec3<f32> {
    let p = i - 1u;
    let t0 = tangent[p];
    let t1 = tangent[i];
    let inverse_chi = 1.0 / (1.0 + dot(t0, t1));
    let binormal = 2.0 * inverse_chi * cross(t0, t1);
    let tilde_t = inverse_chi * (t0 + t1);
    let tilde_m1 = inverse_chi * (m1[p] + m1[i]);
    let tilde_m2 = inverse_chi * (m2[p] + m2[i]);
    let k1 = 0.5 * dot(binormal, m2[p] + m2[i]);
    let k2 = -0.5 * dot(binormal, m1[p] + m1[i]);
    let il0 = inverse_length[p];
    let il1 = inverse_length[i];
    scatter(0u, (-k1 * tilde_t + cross(t1, tilde_m2)) * il0, (-k1 * tilde_t - cross(t0, tilde_m2)) * il1,
        vec2<f32>(-0.5 * dot(binormal, m1[p]), -0.5 * dot(binormal, m1[i])));
    scatter(1u, (-k2 * tilde_t - cross(t1, tilde_m1)) * il0, (-k2 * tilde_t + cross(t0, tilde_m1)) * il1,
        vec2<f32>(-0.5 * dot(binormal, m2[p]), -0.5 * dot(binormal, m2[i])));
    scatter(2u, 0.5 * binormal * il0, 0.5 * binormal * il1, vec2<f32>(-1.0, 1.0));
    let twist = theta[i] - theta[p] + reference_twist[i];
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

// Adds the bending and twisting forces (into `rhs`) and their Gauss–Newton Hessian times `scale`.
fn add_bending_and_twisting(scale: f32) {
    let stiffness = strand_floats[strand * STRAND_FLOATS];
    for (var i = 1u; i < edge_count(); i++) {
        let strain = vertex_strain(i);
        let rest_bend = rest_at(i, 0u);
        let rest_twist = rest_at(i, 1u).x;
        let inverse_voronoi = 1.0 / rest_bend.y;
        let s1 = stiffness.y * inverse_voronoi;
        let s2 = stiffness.z * inverse_voronoi;
        let s3 = stiffness.w * inverse_voronoi;
        let f1 = s1 * (strain.x - rest_bend.z);
        let f2 = s2 * (strain.y - rest_bend.w);
        let f3 = s3 * (strain.z - rest_twist);
        let offset = 4u * (i - 1u);
        for (var a = 0u; a < 11u; a++) {
            rhs[offset + a] += f1 * grad_k1[a] + f2 * grad_k2[a] + f3 * grad_tw[a];
            let w1 = scale * s1 * grad_k1[a];
            let w2 = scale * s2 * grad_k2[a];
            let w3 = scale * s3 * grad_tw[a];
            let row = offset + a;
            for (var b = 0u; b <= a; b++) {
                band[band_index(row, offset + b)] += w1 * grad_k1[b] + w2 * grad_k2[b] + w3 * grad_tw[b];
            }
        }
    }
}

// `product = A d` for the symmetric band, `d` in `product`'s place given as `rhs_source`.
fn band_product(d: ptr<function, array<f32, MAX_DOFS>>) {
    let n = dofs();
    for (var r = 0u; r < n; r++) {
        product[r] = 0.0;
    }
    for (var r = 0u; r < n; r++) {
        let first = select(0u, r - BAND, r >= BAND);
        for (var c = first; c < r; c++) {
            let a = band[band_index(r, c)];
            product[r] += a * (*d)[c];
            product[c] += a * (*d)[r];
        }
        product[r] += band[band_index(r, r)] * (*d)[r];
    }
}

// The capped stretching stiffness of every edge's first-order change of length: `k t tᵀ` on both nodes'
// diagonal blocks and `−k t tᵀ` between them. No stretching force: lengths are the projection's.
fn add_stretch_hessian(inertia: f32) {
    let stiffness = strand_floats[strand * STRAND_FLOATS].x;
    for (var e = 0u; e < edge_count(); e++) {
        let rest_length = rest_at(e, 0u).x;
        let mass = 0.5 * (rest_at(e, 1u).y + rest_at(e + 1u, 1u).y);
        let k = min(stiffness / rest_length, params.stretch_ratio * mass * inertia);
        let t = tangent[e];
        let start = 4u * e;
        for (var a = 0u; a < 3u; a++) {
            for (var b = 0u; b < 3u; b++) {
                let value = k * t[a] * t[b];
                band[band_index(start + 4u + a, start + b)] -= value;
                if b <= a {
                    band[band_index(start + a, start + b)] += value;
                    band[band_index(start + 4u + a, start + 4u + b)] += value;
                }
            }
        }
    }
}

// In-place `L D Lᵀ` of the band; false at a non-positive pivot.
fn factorize() -> bool {
    let n = dofs();
    for (var i = 0u; i < n; i++) {
        let first = select(0u, i - BAND, i >= BAND);
        for (var j = first; j < i; j++) {
            var sum = band[band_index(i, j)];
            let inner = select(0u, j - BAND, j >= BAND);
            for (var k = max(first, inner); k < j; k++) {
                sum -= band[band_index(i, k)] * band[band_index(k, k)] * band[band_index(j, k)];
            }
            band[band_index(i, j)] = sum / band[band_index(j, j)];
        }
        var diagonal = band[band_index(i, i)];
        for (var k = first; k < i; k++) {
            let l = band[band_index(i, k)];
            diagonal -= l * l * band[band_index(k, k)];
        }
        if !(diagonal > 0.0) || !finite(diagonal) {
            return false;
        }
        band[band_index(i, i)] = diagonal;
    }
    return true;
}

// Solves `L D Lᵀ y = rhs` in place.
fn solve() {
    let n = dofs();
    for (var i = 0u; i < n; i++) {
        let first = select(0u, i - BAND, i >= BAND);
        for (var k = first; k < i; k++) {
            rhs[i] -= band[band_index(i, k)] * rhs[k];
        }
    }
    for (var i = 0u; i < n; i++) {
        rhs[i] /= band[band_index(i, i)];
    }
    for (var step = 0u; step < n; step++) {
        let i = n - 1u - step;
        let last = min(i + BAND, n - 1u);
        for (var k = i + 1u; k <= last; k++) {
            rhs[i] -= band[band_index(k, i)] * rhs[k];
        }
    }
}

fn node_inverse_mass(i: u32) -> f32 {
    if i < 2u {
        return 0.0;
    }
    return 1.0 / rest_at(i, 1u).y;
}

fn largest_strain() -> vec2<f32> {
    var worst = 0.0;
    var edge = 0u;
    for (var e = 0u; e < edge_count(); e++) {
        let strain = abs(length(x[e + 1u] - x[e]) / rest_at(e, 0u).x - 1.0);
        if strain > worst || !finite(strain) {
            worst = strain;
            edge = e;
        }
    }
    return vec2<f32>(worst, f32(edge));
}

// The strain single precision resolves on edge `e` where it lies (positions are head-relative, so the
// further a node is from its head's origin, the coarser it is): `RESOLUTION_MARGIN u ((|xₑ| + |xₑ₊₁|)/l + 2)`,
// 2.4e-5 for a 6 mm edge 0.3 m from the origin, 1e-6 for a 5 cm edge at 0.1 m. Never below the step's
// `strain_tolerance`.
fn strain_resolution(e: u32, rest_length: f32) -> f32 {
    let reach = length(x[e]) + length(x[e + 1u]);
    return max(params.strain_tolerance, RESOLUTION_MARGIN * UNIT_ROUNDOFF * (reach / rest_length + 2.0));
}

// The largest edge strain over its resolution (`strain_resolution`): at most 1 where every edge's length
// is as exact as single precision can make it.
fn largest_excess() -> f32 {
    var worst = 0.0;
    for (var e = 0u; e < edge_count(); e++) {
        let rest_length = rest_at(e, 0u).x;
        let excess = abs(length(x[e + 1u] - x[e]) / rest_length - 1.0) / strain_resolution(e, rest_length);
        if excess > worst || !finite(excess) {
            worst = excess;
        }
    }
    return worst;
}

fn mobility(i: u32, v: vec3<f32>) -> vec3<f32> {
    let n = normal[i];
    return node_inverse_mass(i) * (v - dot(n, v) * n);
}

// Fast projection onto the rest lengths (Goldenthal et al. 2007): `x ← x − M⁻¹ ∇Cᵀ λ` with the tridiagonal
// `(∇C M⁻¹ ∇Cᵀ) λ = C`, `C_j = e_j·e_j / L_j − L_j`; a Gauss–Seidel sweep of exact per-edge projections
// where a Newton step would not reduce the error. Touching nodes move only along their surfaces. Stops
// once every edge is within the strain single precision resolves where it lies (`strain_resolution`), or
// when an iteration, sweep included, no longer reduces an error within `STALL_EXCESS` of it (rounding, not
// the lengths, sets it then).
fn project_lengths(iterations: u32) {
    let edges = edge_count();
    var error = largest_excess();
    work_more.w += 1u;
    for (var iteration = 0u; iteration < iterations; iteration++) {
        if error <= 1.0 {
            return;
        }
        work_steps.z += 1u;
        for (var e = 0u; e < edges; e++) {
            let d = x[e + 1u] - x[e];
            let goal = rest_at(e, 0u).x;
            let k = 4.0 * dot(d, mobility(e, d) + mobility(e + 1u, d)) / (goal * goal);
            let free_k = 4.0 * dot(d, d) / (goal * goal) * (node_inverse_mass(e) + node_inverse_mass(e + 1u));
            if k > 1e-6 * free_k && k > 0.0 {
                tri_diagonal[e] = k * (1.0 + 1e-5);
                tri_rhs[e] = dot(d, d) / goal - goal;
            } else {
                tri_diagonal[e] = 0.0;
                tri_rhs[e] = 0.0;
            }
            tri_upper[e] = 0.0;
            if e + 1u < edges {
                let next = x[e + 2u] - x[e + 1u];
                tri_upper[e] = -4.0 * dot(d, mobility(e + 1u, next)) / (goal * rest_at(e + 1u, 0u).x);
            }
        }
        for (var e = 0u; e < edges; e++) {
            if tri_diagonal[e] == 0.0 {
                tri_diagonal[e] = 1.0;
                if e > 0u {
                    tri_upper[e - 1u] = 0.0;
                }
                tri_upper[e] = 0.0;
            }
        }
        // Thomas algorithm.
        tri_diagonal[0] = 1.0 / tri_diagonal[0];
        for (var r = 1u; r < edges; r++) {
            let factor = tri_upper[r - 1u] * tri_diagonal[r - 1u];
            tri_diagonal[r] = 1.0 / (tri_diagonal[r] - factor * tri_upper[r - 1u]);
            tri_rhs[r] -= factor * tri_rhs[r - 1u];
        }
        tri_rhs[edges - 1u] *= tri_diagonal[edges - 1u];
        for (var step = 1u; step < edges; step++) {
            let r = edges - 1u - step;
            tri_rhs[r] = (tri_rhs[r] - tri_upper[r] * tri_rhs[r + 1u]) * tri_diagonal[r];
        }
        // The impulses from the edges as they were (saved in `x_carried`'s place is not free: use m1 as
        // scratch for the edge vectors).
        for (var e = 0u; e < edges; e++) {
            m1[e] = x[e + 1u] - x[e];
        }
        for (var e = 0u; e < edges; e++) {
            let impulse = 2.0 * tri_rhs[e] / rest_at(e, 0u).x * m1[e];
            x[e] += mobility(e, impulse);
            x[e + 1u] -= mobility(e + 1u, impulse);
        }
        var projected = largest_excess();
        if !(projected < error) {
            gauss_seidel_sweep();
            work_steps.w += 1u;
            projected = largest_excess();
            // Stalled near the resolution: rounding sets the error there, and more iterations do not
            // lower it. Further from it (nodes held on colliders' surfaces fighting the lengths), go on.
            if !(projected < error) {
                work_more.z += 1u;
                if projected <= STALL_EXCESS {
                    return;
                }
            }
        }
        error = projected;
    }
}

fn gauss_seidel_sweep() {
    let edges = edge_count();
    for (var sweep = 0u; sweep < 2u * edges; sweep++) {
        let e = select(2u * edges - 1u - sweep, sweep, sweep < edges);
        let d = x[e + 1u] - x[e];
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
        x[e] += excess * start_move;
        x[e + 1u] -= excess * end_move;
    }
}

// Assembles the Newton system at the current iterate; returns false where it does not factorise even
// with the diagonal scaled by `1 + λ`, λ up to 1.
// The first node collider `c` meets (from the third: the root edge is prescribed). A collider holding the
// root inside it leaves the nodes within `HELD_REACH` times the root's depth (along the strand) free of it,
// as on the CPU (`held_reach` in `rod/contact.rs`): hair grows out of it, and is not torn trying to be
// outside.
fn first_met_node(c: u32, thickness: f32) -> u32 {
    let reach = HELD_REACH * max(-touch(c, x[0], thickness).distance, 0.0);
    var arc = rest_at(0u, 0u).x + rest_at(1u, 0u).x;
    var i = 2u;
    while i < nodes && arc <= reach {
        arc += rest_at(i, 0u).x;
        i++;
    }
    return i;
}

// Contact inside the solve, as on the CPU (`rod/contact.rs`): each node within `CONTACT_GAP` of a collider
// (at its end pose, grown by the thickness) gets a stiff one-sided spring along the surface normal,
// `½ k min(d, 0)²` with `k = CONTACT_RATIO m (1/h² + γ/h)`, so that the solve knows what supports the
// strand (a node pressed by its weight sinks `g h² / CONTACT_RATIO`). Nodes held inside a collider with
// the root (`HELD_REACH`) are free of it. `springs[i]` says whether node `i` has one, for the friction.
fn add_contact_springs(inertia: f32) {
    let first = bitcast<u32>(head_row(3u).x);
    let count = bitcast<u32>(head_row(3u).y);
    let thickness = strand_floats[strand * STRAND_FLOATS + 1u].w;
    for (var i = 0u; i < nodes; i++) {
        springs[i] = 0.0;
    }
    for (var k = 0u; k < count; k++) {
        let c = first + k;
        for (var i = first_met_node(c, thickness); i < nodes; i++) {
            let contact = touch(c, x[i], thickness);
            if contact.distance >= CONTACT_GAP {
                continue;
            }
            let stiffness = CONTACT_RATIO * rest_at(i, 1u).y * inertia;
            let n = contact.normal;
            let pressed = stiffness * min(contact.distance, 0.0);
            for (var a = 0u; a < 3u; a++) {
                rhs[4u * i + a] += pressed * n[a];
                for (var b = 0u; b <= a; b++) {
                    band[band_index(4u * i + a, 4u * i + b)] += stiffness * n[a] * n[b];
                }
            }
            springs[i] = 1.0;
        }
    }
}

fn assemble_and_factorize(iteration: u32, h: f32, target_offset: f32) -> bool {
    let n = dofs();
    var regularisation = 0.0;
    loop {
        for (var k = 0u; k < n * WIDTH; k++) {
            band[k] = 0.0;
        }
        for (var k = 0u; k < n; k++) {
            rhs[k] = 0.0;
        }
        edge_frames();
        let damped_scale = 1.0 + params.internal_damping / params.dt;
        add_bending_and_twisting(damped_scale);
        // Internal damping β/dt H (q − q̃) on the deformation since the first guess.
        if iteration > 0u && params.internal_damping > 0.0 {
            var d: array<f32, MAX_DOFS>;
            for (var i = 0u; i < nodes; i++) {
                let offset = x[i] - x_carried[i];
                d[4u * i] = offset.x;
                d[4u * i + 1u] = offset.y;
                d[4u * i + 2u] = offset.z;
                if i < edge_count() {
                    d[4u * i + 3u] = theta[i] - theta_carried[i];
                }
            }
            band_product(&d);
            let factor = params.internal_damping / params.dt / damped_scale;
            for (var k = 0u; k < n; k++) {
                rhs[k] += factor * product[k];
            }
        }
        let inertia = 1.0 / (h * h) + params.air_damping / h;
        add_stretch_hessian(inertia);
        // Inertia, drag relative to the air, gravity.
        let gravity = vec3<f32>(params.gravity_x, params.gravity_y, params.gravity_z);
        let air = head_row(2u).xyz;
        for (var i = 0u; i < nodes; i++) {
            let mass = rest_at(i, 1u).y;
            let offset = x[i] - x_hat[i];
            let relative = offset / h - air;
            // The node's tangent at the step's start: the mean of its edges'.
            var t: vec3<f32>;
            if i == 0u {
                t = normalize(x_start[1] - x_start[0]);
            } else if i == edge_count() {
                t = normalize(x_start[i] - x_start[i - 1u]);
            } else {
                let sum = normalize(x_start[i] - x_start[i - 1u]) + normalize(x_start[i + 1u] - x_start[i]);
                t = select(normalize(x_start[i + 1u] - x_start[i]), normalize(sum), dot(sum, sum) > 1e-12);
            }
            let gamma = mass * params.air_damping;
            let along = 1.0 - params.axial_drag_ratio;
            let drag_force = gamma * (relative - along * dot(t, relative) * t);
            var residual = mass / (h * h) * (offset - h * v_hat[i]) + drag_force - mass * gravity;
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
                residual += mass * k * (x[i] - place) + mass * c * (offset / h - place_velocity);
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
        }
        add_contact_springs(inertia);
        // Twists by backward Euler.
        let dt = params.dt;
        for (var e = 0u; e < edge_count(); e++) {
            let j = rest_at(e, 1u).z;
            let offset = theta[e] - theta_start[e];
            let dof = 4u * e + 3u;
            rhs[dof] += j / (dt * dt) * (offset - dt * theta_rate[e]) + params.air_damping * j / dt * offset;
            band[band_index(dof, dof)] += j * (1.0 / (dt * dt) + params.air_damping / dt);
        }
        if regularisation > 0.0 {
            for (var k = 0u; k < n; k++) {
                band[band_index(k, k)] *= 1.0 + regularisation;
            }
        }
        // The root edge prescribed: its unknowns move by their remaining displacement.
        var prescribed: array<f32, 7>;
        let p0 = root_target(0u) - x[0];
        let p1 = root_target(1u) - x[1];
        prescribed[0] = p0.x;
        prescribed[1] = p0.y;
        prescribed[2] = p0.z;
        prescribed[3] = target_offset;
        prescribed[4] = p1.x;
        prescribed[5] = p1.y;
        prescribed[6] = p1.z;
        for (var r = 0u; r < min(n, 7u + BAND); r++) {
            var coupling = 0.0;
            for (var c = 0u; c < 7u; c++) {
                if (r >= c && r - c <= BAND) {
                    coupling += band[band_index(r, c)] * prescribed[c];
                } else if (c > r && c - r <= BAND) {
                    coupling += band[band_index(c, r)] * prescribed[c];
                }
            }
            rhs[r] += coupling;
        }
        for (var r = 0u; r < 7u; r++) {
            for (var c = select(0u, r - BAND, r >= BAND); c < r; c++) {
                band[band_index(r, c)] = 0.0;
            }
            for (var below = r + 1u; below <= min(r + BAND, n - 1u); below++) {
                band[band_index(below, r)] = 0.0;
            }
            band[band_index(r, r)] = 1.0;
            rhs[r] = -prescribed[r];
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

// The signed distance of `p` (head-relative) from collider `c` at its end pose grown by `thickness`, the
// closest surface point and the outward normal (head-relative): radially for a sphere, from the axis for a
// capsule, along the gradient from the radial point for an ellipsoid, straight up for a plane.
struct Touch {
    distance: f32,
    surface: vec3<f32>,
    normal: vec3<f32>,
}

fn touch(c: u32, p: vec3<f32>, thickness: f32) -> Touch {
    let centre = colliders[c * COLLIDER_ROWS + 2u].xyz;
    let rotation = colliders[c * COLLIDER_ROWS + 3u];
    let shape = colliders[c * COLLIDER_ROWS + 4u];
    let local = inverse_rotate(rotation, p - centre);
    var result: Touch;
    var surface = local;
    var n = vec3<f32>(0.0, 1.0, 0.0);
    var distance = 1e30;
    if shape.w == 0.0 {
        let radius = shape.x + thickness;
        let r = length(local);
        if r > 0.0 {
            n = local / r;
        }
        distance = r - radius;
        surface = n * radius;
    } else if shape.w == 1.0 {
        let radius = shape.x + thickness;
        let axis = vec3<f32>(0.0, clamp(local.y, -shape.y, shape.y), 0.0);
        let away = local - axis;
        let r = length(away);
        n = vec3<f32>(1.0, 0.0, 0.0);
        if r > 0.0 {
            n = away / r;
        }
        distance = r - radius;
        surface = axis + n * radius;
    } else if shape.w == 2.0 {
        let axes = shape.xyz + vec3<f32>(thickness);
        let scaled = length(local / axes);
        if scaled > 0.0 {
            let on = local / scaled;
            n = normalize(on / (axes * axes));
            // The distance along the normal from the radial point, to first order.
            distance = dot(local - on, n);
            surface = on;
        } else {
            distance = -axes.y;
            surface = vec3<f32>(0.0, axes.y, 0.0);
        }
    } else if shape.w == 3.0 {
        distance = local.y - thickness;
        surface = vec3<f32>(local.x, thickness, local.z);
    }
    result.distance = distance;
    result.surface = centre + rotate(rotation, surface);
    result.normal = rotate(rotation, n);
    return result;
}

// Nodes inside a collider put on its surface; with `friction`, their slip over the step relative to the
// collider (from where the node was at the start, in the collider's start frame) is cancelled up to μ times
// the push (Macklin et al. 2014). Returns whether any node moved.
fn push_out(friction: bool) -> bool {
    let first = bitcast<u32>(head_row(3u).x);
    let count = bitcast<u32>(head_row(3u).y);
    let thickness = strand_floats[strand * STRAND_FLOATS + 1u].w;
    var moved = false;
    for (var k = 0u; k < count; k++) {
        let c = first + k;
        for (var i = first_met_node(c, thickness); i < nodes; i++) {
            let contact = touch(c, x[i], thickness);
            if contact.distance >= 0.0 {
                continue;
            }
            var goal = contact.surface;
            if friction {
                let mu = colliders[c * COLLIDER_ROWS + 2u].w;
                // Where the node started, carried with the collider to its end pose.
                let start_local = inverse_rotate(colliders[c * COLLIDER_ROWS + 1u], x_start[i] - colliders[c * COLLIDER_ROWS].xyz);
                let carried = colliders[c * COLLIDER_ROWS + 2u].xyz + rotate(colliders[c * COLLIDER_ROWS + 3u], start_local);
                let slip = goal - carried;
                let tangential = slip - dot(slip, contact.normal) * contact.normal;
                // The normal push this step: the spring's force in the solve (as a displacement over the
                // step, `k d h² / m = CONTACT_RATIO d`) and the push-out itself.
                let limit = mu * -contact.distance * (1.0 + CONTACT_RATIO * springs[i]);
                let size = length(tangential);
                if size <= limit {
                    goal -= tangential;
                } else {
                    goal -= tangential * (limit / size);
                }
                // Back onto the surface after the friction's tangential move.
                let again = touch(c, goal, thickness);
                if again.distance < 0.0 {
                    goal = again.surface;
                }
            }
            // Moved only by more than the position's rounding: a node left on the surface to within rounding
            // ends the rounds.
            let shift = length(goal - x[i]);
            moved = moved || shift > MOVE_MARGIN * UNIT_ROUNDOFF * length(x[i]);
            x[i] = goal;
            normal[i] = contact.normal;
        }
    }
    return moved;
}

fn reset_to_rest() {
    for (var i = 0u; i < nodes; i++) {
        let pose = rest_at(i, 2u);
        let frame = rest_at(i, 3u);
        x[i] = rotate(head_row(0u), pose.xyz);
        theta[i] = pose.w;
        director[i] = rotate(head_row(0u), frame.xyz);
        reference_twist[i] = frame.w;
        x_hat[i] = x[i];
        theta_start[i] = theta[i];
    }
}

// Whether a value is finite, from its bits: WGSL lets an implementation assume no NaN or infinity in
// arithmetic and comparisons, so only the exponent's bits tell reliably.
fn finite(v: f32) -> bool {
    return (bitcast<u32>(v) & 0x7f800000u) != 0x7f800000u;
}

fn finite3(v: vec3<f32>) -> bool {
    return finite(v.x) && finite(v.y) && finite(v.z);
}

@compute @workgroup_size(32)
fn step(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    strand = id.x + id.y * groups.x * WORKGROUP;
    if strand >= params.strands {
        return;
    }
    let words = strand_words[strand * STRAND_WORDS];
    nodes = words.x;
    head = words.y;
    if nodes < 3u || nodes > MAX_NODES {
        return;
    }
    var flags = status[strand].x;
    if params.restart != 0u {
        flags = flags & ~HAS_HISTORY;
    }
    let shift = head_row(1u).xyz;
    let dt = params.dt;
    let two_step = params.bdf2 != 0u && (flags & HAS_HISTORY) != 0u;
    let h = select(dt, 2.0 / 3.0 * dt, two_step);

    // 1. Load, shift to the head's new translation; the scheme's prediction.
    for (var i = 0u; i < nodes; i++) {
        let p = state[state_index(i, 0u)];
        let v = state[state_index(i, 1u)];
        x[i] = p.xyz + shift;
        theta[i] = p.w;
        theta_rate[i] = v.w;
        x_start[i] = x[i];
        theta_start[i] = p.w;
        let frame = state[state_index(i, 4u)];
        director[i] = frame.xyz;
        reference_twist[i] = frame.w;
        normal[i] = vec3<f32>(0.0);
        if two_step {
            let before = state[state_index(i, 2u)].xyz + shift;
            let v_before = state[state_index(i, 3u)].xyz;
            x_hat[i] = (4.0 * x[i] - before) / 3.0;
            v_hat[i] = (4.0 * v.xyz - v_before) / 3.0;
        } else {
            x_hat[i] = x[i];
            v_hat[i] = v.xyz;
        }
        // The step's start velocity, kept for the history in `x_carried`'s place until the carry.
        m2[i] = v.xyz;
    }
    for (var e = 0u; e < edge_count(); e++) {
        tangent[e] = normalize(x[e + 1u] - x[e]);
    }
    // The history this step leaves: positions and velocities at its start.
    for (var i = 0u; i < nodes; i++) {
        state[state_index(i, 2u)] = vec4<f32>(x_start[i], 0.0);
        state[state_index(i, 3u)] = vec4<f32>(m2[i], 0.0);
    }

    // 2. The first guess: carried with the root.
    carry_with_root();
    for (var i = 0u; i < nodes; i++) {
        x_carried[i] = x[i];
        theta_carried[i] = theta[i];
    }

    // 3. Newton iterations.
    var fault = 0u;
    var fault_at = 0u;
    let target_tangent = normalize(root_target(1u) - root_target(0u));
    for (var iteration = 0u; iteration < params.newton_iterations; iteration++) {
        let offset = root_twist_offset(target_tangent, root_target(2u));
        if !assemble_and_factorize(iteration, h, offset) {
            fault = FAULT_NOT_DEFINITE;
            break;
        }
        for (var k = 0u; k < dofs(); k++) {
            rhs[k] = -rhs[k];
        }
        solve();
        // The trust region: no edge (but the root's) turns by more than `max_rotation`.
        var largest = 0.0;
        for (var e = 1u; e < edge_count(); e++) {
            let d = x[e + 1u] - x[e];
            let change = vec3<f32>(rhs[4u * e + 4u], rhs[4u * e + 5u], rhs[4u * e + 6u])
                - vec3<f32>(rhs[4u * e], rhs[4u * e + 1u], rhs[4u * e + 2u]);
            let along = dot(change, d) / dot(d, d);
            let turn = length(change - along * d) / length(d) + max(-along - 0.5, 0.0);
            largest = select(max(largest, turn), turn, !finite(turn));
        }
        if !finite(largest) {
            fault = FAULT_NON_FINITE;
            break;
        }
        let fraction = select(1.0, params.max_rotation / largest, largest > params.max_rotation);

        for (var i = 0u; i < nodes; i++) {
            x[i] += fraction * vec3<f32>(rhs[4u * i], rhs[4u * i + 1u], rhs[4u * i + 2u]);
            if i < edge_count() {
                theta[i] += fraction * rhs[4u * i + 3u];
            }
        }
        work_steps.y += 1u;
        let last = iteration + 1u == params.newton_iterations;
        if last {
            // Exactly on the root's targets.
            x[0] = root_target(0u);
            x[1] = root_target(1u);
            theta[0] += root_twist_offset(target_tangent, root_target(2u));
        }
        // Before another iteration the lengths need only be near enough for its linearisation (its solve
        // has no stretching force): one projection iteration, which takes the update's second-order
        // stretch (½ turn², up to 5e-3) to ~1e-5. After the last, as exact as single precision resolves.
        // (No projection before another iteration saves 0.4 iterations a strand-step on the shaken head
        // but leaves a held strand 7 % further from the CPU's: `tests/gpu_step.rs`.)
        project_lengths(select(1u, params.projection_iterations, last));

        refresh_frames();
    }

    // 4. Contact with the head's colliders. A strand that cannot be put outside them with its lengths kept
    // (one deep inside a collider that holds its root, say) keeps its solved state for this step instead
    // (status bit `CONTACT_GIVEN_UP`): it stays whole and comes out as far as it can in later steps.
    flags = flags & ~CONTACT_GIVEN_UP;
    if fault == 0u && bitcast<u32>(head_row(3u).y) > 0u {
        for (var i = 0u; i < nodes; i++) {
            x_carried[i] = x[i];
        }
        for (var round = 0u; round < params.contact_rounds; round++) {
            work_more.x += 1u;
            if !push_out(round == 0u) {
                break;
            }
            project_lengths(params.projection_iterations);
        }
        let pushed = largest_strain().x;
        if !(pushed <= params.strain_bound) {
            for (var i = 0u; i < nodes; i++) {
                x[i] = x_carried[i];
                normal[i] = vec3<f32>(0.0);
            }
            flags = flags | CONTACT_GIVEN_UP;
        }
        refresh_frames();
    }

    // 5. Checks.
    var strain = largest_strain();
    if fault == 0u {
        for (var i = 0u; i < nodes; i++) {
            if !finite3(x[i]) || !finite(theta[i]) {
                fault = FAULT_NON_FINITE;
                fault_at = i;
                break;
            }
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
        for (var i = 0u; i < nodes; i++) {
            x_start[i] = x[i];
        }
        flags = flags & ~HAS_HISTORY;
        strain = largest_strain();
    } else {
        flags = flags | HAS_HISTORY;
    }

    // 6. Velocities and the state written back.
    let count = nodes;
    let stopped = fault != 0u;
    for (var i = 0u; i < count; i++) {
        let p = x[i];
        let v = select((p - x_hat[i]) / h, vec3<f32>(0.0), stopped);
        let rate = select((theta[i] - theta_start[i]) / dt, 0.0, stopped);
        state[state_index(i, 0u)] = vec4<f32>(p, theta[i]);
        state[state_index(i, 1u)] = vec4<f32>(v, rate);
        state[state_index(i, 4u)] = vec4<f32>(director[i], reference_twist[i]);
    }
    // The failed steps' count keeps the last one's reason in its top bits, and `y` where it was, so that a
    // read-back every few steps still says why.
    let before = status[strand];
    var failures = before.w;
    var at = before.y;
    if stopped {
        failures = (((failures & FAULT_COUNT) + 1u) & FAULT_COUNT) | (fault << 28u);
        at = fault_at;
    }
    let reported = select(strain.x, failing_strain, fault == FAULT_OVER_STRAINED);
    status[strand] = vec4<u32>((flags & (HAS_HISTORY | CONTACT_GIVEN_UP)) | fault, at, bitcast<u32>(reported), failures);
    work_steps.x = 1u;
    let row = strand * WORK_ROWS;
    work[row] = work[row] + work_steps;
    work[row + 1u] = work[row + 1u] + work_more;
}
