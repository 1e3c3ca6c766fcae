// The strands stepped by `step.wgsl` handed to the renderer's follower placement (`render/followers.wgsl`)
// without leaving the GPU: one invocation per guide of a head, writing what the CPU would have sent for
// it (`render/feed.rs`): its nodes in world space, its thickness and flags, and, in place of the frame
// codes the CPU sends, the director `m1` of each node's edge that the placement's `frames` pass would have
// walked from them (the root edge's at the root).

struct Params {
    // Nodes of every strand in the step's buffers (the length of a row plane), guides of this head, where
    // the guide words start in `guide_data` (words), unused.
    total_nodes: u32,
    guides: u32,
    guides_offset: u32,
    unused: u32,
    // The head's translation after the last step: the origin of its strands' positions, m.
    origin: vec3<f32>,
}

// As in `step.wgsl`.
const STRAND_FLOATS: u32 = 4u;
const FAULTS: u32 = 14u;
// As in `followers.wgsl`.
const GUIDE_SNAP: u32 = 1u;
const WORKGROUP: u32 = 64u;

@group(0) @binding(0) var<uniform> params: Params;
// Per strand: node count, head, its first node in the state's row planes, 0.
@group(0) @binding(1) var<storage, read> strand_words: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> strand_floats: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> state: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> status: array<vec4<u32>>;
// Per guide: its strand and its first guide node; then one past the last guide node.
@group(0) @binding(5) var<storage, read> guide_strands: array<vec2<u32>>;
@group(0) @binding(6) var<storage, read_write> guide_data: array<u32>;
@group(0) @binding(7) var<storage, read_write> guide_frames: array<vec4<f32>>;

// Row `row` of node `node` of strand `strand` (`step.wgsl`'s layout).
fn state_at(node: u32, row: u32, strand: u32) -> vec4<f32> {
    return state[row * params.total_nodes + strand_words[strand].z + node];
}

@compute @workgroup_size(64)
fn gather(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let guide = id.x + id.y * groups.x * WORKGROUP;
    if guide >= params.guides {
        return;
    }
    let strand = guide_strands[guide].x;
    let first = guide_strands[guide].y;
    let end = guide_strands[guide + 1u].y;
    let thickness = strand_floats[strand * STRAND_FLOATS + 1u].w;
    // A strand that faulted was put back in its rest pose: nothing to interpolate from.
    let snap = select(0u, GUIDE_SNAP, (status[strand].x & FAULTS) != 0u);
    guide_data[params.guides_offset + 2u * guide] = bitcast<u32>(thickness);
    guide_data[params.guides_offset + 2u * guide + 1u] = snap;
    var previous = state_at(0u, 0u, strand).xyz;
    for (var node = first; node < end; node++) {
        let i = node - first;
        let p = state_at(i, 0u, strand);
        let world = params.origin + p.xyz;
        guide_data[3u * node] = bitcast<u32>(world.x);
        guide_data[3u * node + 1u] = bitcast<u32>(world.y);
        guide_data[3u * node + 2u] = bitcast<u32>(world.z);
        if i == 0u {
            continue;
        }
        // Edge `i − 1`: its material director `m1 = cos θ u + sin θ (t × u)` (`refresh_frames` in
        // `step.wgsl`).
        let t = normalize(p.xyz - previous);
        let edge = state_at(i - 1u, 0u, strand);
        let u = state_at(i - 1u, 4u, strand).xyz;
        let m1 = cos(edge.w) * u + sin(edge.w) * cross(t, u);
        guide_frames[node] = vec4<f32>(m1, 0.0);
        if i == 1u {
            guide_frames[first] = vec4<f32>(m1, 0.0);
        }
        previous = p.xyz;
    }
}
