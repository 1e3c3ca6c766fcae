// Hair strands as camera-facing ribbons (bevy_hair_sim::render): the vertex stage expands each node of a
// hair into the two sides of a ribbon; the fragment stage shades it with Kajiya–Kay's hair model and
// Scheuermann's two shifted highlights under Bevy's lights and shadows. The same vertex stage, compiled
// with PREPASS_PIPELINE, draws the hair into shadow maps (ribbons then face the light).

#import bevy_pbr::mesh_view_bindings::view
#import bevy_pbr::mesh_functions::{get_world_from_local, get_previous_world_from_local}

#ifdef PREPASS_PIPELINE
#ifdef MOTION_VECTOR_PREPASS
#import bevy_pbr::prepass_bindings::previous_view_uniforms
#endif
#else
#import bevy_pbr::{
    mesh_view_bindings as view_bindings,
    mesh_view_types,
    clustered_forward as clustering,
    shadows,
    lighting,
}
#ifdef TONEMAP_IN_SHADER
#import bevy_core_pipeline::tonemapping::tone_mapping
#endif
#endif

struct HairShading {
    root_color: vec4<f32>,
    tip_color: vec4<f32>,
    // primary shift, secondary shift (rad), primary and secondary lobes' squared widths (rad²)
    highlights: vec4<f32>,
    // specular strength, colour variation, minimum width (pixels), root occlusion
    parameters: vec4<f32>,
    // light penetration (m; 0: the shadow maps' hard shadows), highlight filtering, unused × 2
    deep_shadows: vec4<f32>,
}

@group(#{MATERIAL_BIND_GROUP}) @binding(0) var<storage, read> positions: array<f32>;
@group(#{MATERIAL_BIND_GROUP}) @binding(1) var<uniform> shading: HairShading;
#ifdef MOTION_VECTOR_PREPASS
// The positions drawn the frame before, laid out like `positions` (`HairMesh::previous_positions_buffer`).
@group(#{MATERIAL_BIND_GROUP}) @binding(2) var<storage, read> previous_positions: array<f32>;
#endif

struct Vertex {
    // node, hair, side | along << 1 | (nodes − 1) << 16, radius (f32 bits)
    @location(0) hair: vec4<u32>,
#ifndef PREPASS_PIPELINE
    // The hair's own colour at this node, sRGB bytes with alpha 255, or 0: the appearance's colours.
    @location(1) color: u32,
#endif
}

// A node where it is drawn: where it was stepped, carried by the mesh's transform onto the head as it is
// this frame (`HeadMotion::drawn_to_now`).
fn node_position(node: u32, world_from_local: mat4x4<f32>) -> vec3<f32> {
    let stepped = vec3(positions[3u * node], positions[3u * node + 1u], positions[3u * node + 2u]);
    return (world_from_local * vec4(stepped, 1.0)).xyz;
}

fn is_orthographic() -> bool {
    return view.clip_from_view[3][3] == 1.0;
}

// Unit direction from `position` towards the eye (for an orthographic view, the view's backward axis).
fn towards_eye(position: vec3<f32>) -> vec3<f32> {
    if is_orthographic() {
        return normalize(view.world_from_view[2].xyz);
    }
    return normalize(view.world_position - position);
}

struct Ribbon {
    world_position: vec3<f32>,
    // The node it is expanded from.
    node_position: vec3<f32>,
    tangent: vec3<f32>,
    across: vec3<f32>,
    side: f32,
    along: f32,
    coverage: f32,
}

// The ribbon vertex of a hair vertex: the node moved sideways, along tangent × (direction to the eye), by
// half the drawn width; the drawn width is the hair's diameter, or `min_pixel_width` pixels where that is
// wider, with the coverage lowered in proportion (`bevy_hair_sim::render::ribbon_width`).
fn ribbon(vertex: Vertex, instance_index: u32) -> Ribbon {
    let world_from_local = get_world_from_local(instance_index);
    let node = vertex.hair.x;
    let packed = vertex.hair.z;
    let side = f32(packed & 1u) * 2.0 - 1.0;
    let along = (packed >> 1u) & 0x7fffu;
    let last = packed >> 16u;
    let position = node_position(node, world_from_local);
    let previous = node_position(select(node - 1u, node, along == 0u), world_from_local);
    let next = node_position(select(node + 1u, node, along >= last), world_from_local);
    var tangent = next - previous;
    tangent = select(vec3(0.0, 1.0, 0.0), normalize(tangent), dot(tangent, tangent) > 1e-20);
    let eye = towards_eye(position);
    var across = cross(tangent, eye);
    if dot(across, across) < 1e-12 {
        // Seen end-on: any direction across the hair.
        across = cross(tangent, select(vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), abs(tangent.x) > 0.9));
    }
    across = normalize(across);
    // World size of one pixel at the node: 2 w / (viewport height · clip_from_view[1][1]).
    let clip_w = (view.clip_from_world * vec4(position, 1.0)).w;
    let pixel = 2.0 * clip_w / (view.viewport.w * view.clip_from_view[1][1]);
    let diameter = 2.0 * bitcast<f32>(vertex.hair.w);
    let width = max(diameter, shading.parameters.z * pixel);
    var out: Ribbon;
    out.world_position = position + across * (0.5 * side * width);
    out.node_position = position;
    out.tangent = tangent;
    out.across = across;
    out.side = side;
    out.along = select(0.0, f32(along) / f32(max(last, 1u)), last > 0u);
    out.coverage = select(0.0, diameter / width, width > 0.0);
    return out;
}

// A well-mixed hash of a hair's index to 0 … 1 (PCG, Jarzynski and Olano 2020).
fn hash01(value: u32) -> f32 {
    let state = value * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return f32((word >> 22u) ^ word) / 4294967295.0;
}

// A seed from the view's sub-pixel jitter (Bevy's `TemporalJitter`, which TAA moves through eight offsets,
// one a frame), 0 without jitter: the projection's `z` column (perspective) and `w` column (orthographic)
// carry it. The main pass and the prepass see the same view, so they draw the same pattern.
fn jitter_seed() -> u32 {
    let projection = view.clip_from_view;
    return (bitcast<u32>(projection[2][0]) * 0x27d4eb2du) ^ (bitcast<u32>(projection[2][1]) * 0x165667b1u)
        ^ (bitcast<u32>(projection[3][0]) * 0x9e3779b1u) ^ (bitcast<u32>(projection[3][1]) * 0x85ebca77u);
}

// The samples of the pixel at `position` that hair `hair` of coverage `coverage` covers (0: none, and the
// fragment is discarded). Multisampled, a random subset of the pixel's samples, as many as the coverage is
// worth, drawn per hair and pixel, so that hairs over each other cover independent samples and add up as
// layers of real hair do (alpha to coverage's fixed pattern per alpha would stack every hair on the same
// samples); without multisampling, the whole pixel or none, with the coverage as the chance. The draw
// changes with the view's jitter: under TAA every frame of its cycle covers other pixels and samples, and
// TAA's history averages them into the hair's coverage; without jitter it stays the same from frame to
// frame (no shimmer).
fn covered_samples(coverage: f32, position: vec4<f32>, hair: u32) -> u32 {
    let hash = u32(position.x) * 1973u + u32(position.y) * 9277u + hair * 26699u + jitter_seed();
#ifdef HAIR_MULTISAMPLED
    let samples = #{HAIR_MSAA_SAMPLES}u;
    let covered = min(u32(coverage * f32(samples) + hash01(hash)), samples);
    let rotation = u32(hash01(hash ^ 0x5bd1e995u) * f32(samples)) % samples;
    let all = (1u << samples) - 1u;
    let first = (1u << covered) - 1u;
    return ((first << rotation) | (first >> (samples - rotation))) & all;
#else
    return select(0u, 0xffffffffu, coverage >= hash01(hash));
#endif
}

#ifdef PREPASS_PIPELINE

// Bevy's prepass vertex output, with the hair's coverage and index for the same samples as the main pass.
struct HairPrepassOutput {
    @builtin(position) position: vec4<f32>,
    @location(0) world_position: vec4<f32>,
#ifdef MOTION_VECTOR_PREPASS
    @location(1) previous_world_position: vec4<f32>,
#endif
#ifdef NORMAL_PREPASS_OR_DEFERRED_PREPASS
    @location(2) world_normal: vec3<f32>,
#endif
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    @location(3) unclipped_depth: f32,
#endif
    @location(4) coverage: f32,
    @location(5) @interpolate(flat) hair: u32,
}

@vertex
fn vertex(vertex: Vertex, @builtin(instance_index) instance_index: u32) -> HairPrepassOutput {
    let ribbon = ribbon(vertex, instance_index);
    var out: HairPrepassOutput;
    out.world_position = vec4(ribbon.world_position, 1.0);
    out.position = view.clip_from_world * out.world_position;
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    out.unclipped_depth = out.position.z;
    out.position.z = min(out.position.z, 1.0);
#endif
#ifdef NORMAL_PREPASS_OR_DEFERRED_PREPASS
    out.world_normal = towards_eye(ribbon.world_position);
#endif
#ifdef MOTION_VECTOR_PREPASS
    // Where this ribbon vertex was drawn the frame before: its node there, under the mesh's transform
    // then, with the same offset across the hair (a hair's width is far below a frame's motion).
    let node = vertex.hair.x;
    let before = vec3(previous_positions[3u * node], previous_positions[3u * node + 1u], previous_positions[3u * node + 2u]);
    let previous_node = (get_previous_world_from_local(instance_index) * vec4(before, 1.0)).xyz;
    out.previous_world_position = vec4(previous_node + (ribbon.world_position - ribbon.node_position), 1.0);
#endif
    out.coverage = ribbon.coverage;
    out.hair = vertex.hair.y;
    return out;
}

struct HairPrepassFragmentOutput {
#ifdef NORMAL_PREPASS
    @location(0) normal: vec4<f32>,
#endif
#ifdef MOTION_VECTOR_PREPASS
    @location(1) motion_vector: vec2<f32>,
#endif
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    @builtin(frag_depth) frag_depth: f32,
#endif
    // Every sample the ribbon covers, but for a camera's prepass (`HAIR_CAMERA_PREPASS`).
    @builtin(sample_mask) sample_mask: u32,
}

// Bevy's prepass outputs (as its default prepass fragment writes them), on the samples the main pass
// covers: a camera's depth prepass that took the whole ribbon would hide the samples a hair leaves to the
// hairs behind it. Shadow maps take the whole ribbon, as without this stage. (Bevy runs it for a shadow
// map too, where the material may discard, without saying `PREPASS_FRAGMENT`: it is always there.)
@fragment
fn fragment(in: HairPrepassOutput) -> HairPrepassFragmentOutput {
    var out: HairPrepassFragmentOutput;
    out.sample_mask = 0xffffffffu;
#ifdef NORMAL_PREPASS
    out.normal = vec4(in.world_normal * 0.5 + vec3(0.5), 1.0);
#endif
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    out.frag_depth = in.unclipped_depth;
#endif
#ifdef MOTION_VECTOR_PREPASS
    let clip_position_t = view.unjittered_clip_from_world * in.world_position;
    let clip_position = clip_position_t.xy / clip_position_t.w;
    let previous_clip_position_t = previous_view_uniforms.clip_from_world * in.previous_world_position;
    let previous_clip_position = previous_clip_position_t.xy / previous_clip_position_t.w;
    // UV offsets, as Bevy's prepass writes them: half the clip-space difference, V pointing down.
    out.motion_vector = (clip_position - previous_clip_position) * vec2(0.5, -0.5);
#endif
#ifdef HAIR_CAMERA_PREPASS
    out.sample_mask = covered_samples(in.coverage, in.position, in.hair);
    if out.sample_mask == 0u {
        discard;
    }
#endif
    return out;
}

#else // PREPASS_PIPELINE

struct HairVertexOutput {
    @builtin(position) position: vec4<f32>,
    @location(0) world_position: vec3<f32>,
    @location(1) tangent: vec3<f32>,
    @location(2) across: vec3<f32>,
    // −1 … 1 across the ribbon
    @location(3) side: f32,
    // 0 at the root … 1 at the tip
    @location(4) along: f32,
    @location(5) coverage: f32,
    @location(6) @interpolate(flat) hair: u32,
    // The hair's own colour (sRGB, alpha 1), or alpha 0: the appearance's colours.
    @location(7) color: vec4<f32>,
}

@vertex
fn vertex(vertex: Vertex, @builtin(instance_index) instance_index: u32) -> HairVertexOutput {
    let ribbon = ribbon(vertex, instance_index);
    var out: HairVertexOutput;
    out.position = view.clip_from_world * vec4(ribbon.world_position, 1.0);
    out.world_position = ribbon.world_position;
    out.tangent = ribbon.tangent;
    out.across = ribbon.across;
    out.side = ribbon.side;
    out.along = ribbon.along;
    out.coverage = ribbon.coverage;
    out.hair = vertex.hair.y;
    out.color = unpack4x8unorm(vertex.color);
    return out;
}

// sRGB's transfer function, decoded: an sRGB value 0 … 1 to linear.
fn srgb_to_linear(color: vec3<f32>) -> vec3<f32> {
    return select(pow((color + 0.055) / 1.055, vec3(2.4)), color / 12.92, color <= vec3(0.04045));
}


struct HairSurface {
    color: vec3<f32>,
    tangent: vec3<f32>,
    normal: vec3<f32>,
    eye: vec3<f32>,
    // Tangents tilted towards the root (primary highlight) and the tip (secondary).
    primary_tangent: vec3<f32>,
    secondary_tangent: vec3<f32>,
    sparkle: f32,
    // The primary and secondary lobes' exponents and peaks, filtered over the pixel (`highlight_lobes`).
    lobes: vec4<f32>,
}

// The two highlights' exponents and peak scales once widened by the turn of their shifted tangents over
// the pixel (`HairAppearance::highlight_filtering`): a lobe exp(−Δ²/2β²) averaged over a spread σ² of
// directions is about exp(−Δ²/2(β² + σ²)) with its peak lowered by β/√(β² + σ²), the same integral.
// Derivatives need uniform control flow: called once, before any light is shaded.
fn highlight_lobes(primary_tangent: vec3<f32>, secondary_tangent: vec3<f32>) -> vec4<f32> {
    let filtering = shading.deep_shadows.y;
    // The turn per pixel, rad² (unit vectors: the derivatives' lengths are angles), at most a right angle's.
    let turn = vec2(
        dot(dpdx(primary_tangent), dpdx(primary_tangent)) + dot(dpdy(primary_tangent), dpdy(primary_tangent)),
        dot(dpdx(secondary_tangent), dpdx(secondary_tangent)) + dot(dpdy(secondary_tangent), dpdy(secondary_tangent)),
    );
    let widths = shading.highlights.zw;
    let filtered = widths + min(filtering * turn, vec2(2.5));
    return vec4(1.0 / filtered, sqrt(widths / filtered));
}

// Light reflected towards the eye from light arriving along `light` (unit, towards the light) with
// irradiance `radiance` (before the cosine): Kajiya–Kay diffuse sin(t, l) / π, wrapped around the fibre,
// plus the two shifted highlights sin(t', h)^p.
fn shade(surface: HairSurface, light: vec3<f32>, radiance: vec3<f32>) -> vec3<f32> {
    let sin_tl = sqrt(max(1.0 - pow(dot(surface.tangent, light), 2.0), 0.0));
    // The side of the fibre away from the light gets less: a soft cosine around the cylinder.
    let wrap = saturate((dot(surface.normal, light) + 0.5) / 1.5);
    let diffuse = surface.color * sin_tl * wrap / 3.14159265;
    let half_vector = normalize(light + surface.eye);
    let primary = surface.lobes.z
        * pow(sqrt(max(1.0 - pow(dot(surface.primary_tangent, half_vector), 2.0), 0.0)), surface.lobes.x);
    let secondary = surface.lobes.w
        * pow(sqrt(max(1.0 - pow(dot(surface.secondary_tangent, half_vector), 2.0), 0.0)), surface.lobes.y);
    // A directional fade after Scheuermann's: highlights weaken where the tangent points away from the light.
    let facing = smoothstep(-1.0, 0.0, dot(surface.tangent, light)) * 0.5 + 0.5;
    let specular = shading.parameters.x * wrap * facing
        * (vec3(primary) + secondary * surface.sparkle * surface.color * 4.0);
    return (diffuse + specular) * radiance;
}

struct HairFragmentOutput {
    @location(0) color: vec4<f32>,
#ifdef MULTISAMPLED
    @builtin(sample_mask) sample_mask: u32,
#endif
}

// The share of directional light `light_id`'s light that reaches `position` through the hair in front of
// it (TressFX's deep shadow from an ordinary shadow map): `exp(−d / penetration)`, `d` the depth, m,
// between the point and the nearest thing the light's shadow map holds there (another hair, or the head,
// whose depth darkens it fully), averaged over 3 × 3 texels of the cascade the point is in. Light reaches
// hair behind a few hairs dimmed rather than not at all, as it does through real hair.
fn light_through_hair(light_id: u32, position: vec3<f32>, view_z: f32, penetration: f32) -> f32 {
    let light = &view_bindings::lights.directional_lights[light_id];
    let cascade_index = shadows::get_cascade_index(light_id, view_z);
    if cascade_index >= (*light).num_cascades {
        return 1.0;
    }
    let local = shadows::world_to_directional_light_local(light_id, cascade_index, vec4(position, 1.0));
    if local.w == 0.0 {
        return 1.0;
    }
    // Depth is `clip_from_world`'s third row times the position (orthographic): its length is depth per metre.
    let clip = (*light).cascades[cascade_index].clip_from_world;
    let depth_per_metre = length(vec3(clip[0][2], clip[1][2], clip[2][2]));
    let size = vec2<i32>(textureDimensions(view_bindings::directional_shadow_textures));
    let texel = vec2<i32>(local.xy * vec2<f32>(size));
    let layer = i32((*light).depth_texture_base_index + cascade_index);
    var light_share = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let at = clamp(texel + vec2(dx, dy), vec2(0), size - 1);
#ifdef NO_ARRAY_TEXTURES_SUPPORT
            let nearest = textureLoad(view_bindings::directional_shadow_textures, at, 0);
#else
            let nearest = textureLoad(view_bindings::directional_shadow_textures, at, layer, 0);
#endif
            // Reversed depth: what lies nearer the light has the greater depth.
            let depth = max(nearest - local.z, 0.0) / depth_per_metre;
            light_share += exp(-depth / penetration);
        }
    }
    return light_share / 9.0;
}

@fragment
fn fragment(in: HairVertexOutput) -> HairFragmentOutput {
    let tangent = normalize(in.tangent);
    let eye = towards_eye(in.world_position);
    // The fibre is a cylinder seen across: its normal turns from −across to +across over the ribbon.
    let facing = normalize(eye - tangent * dot(eye, tangent));
    let across = normalize(in.across);
    let side = clamp(in.side, -1.0, 1.0);
    let normal = normalize(side * across + sqrt(max(1.0 - side * side, 0.0)) * facing);

    let variation = shading.parameters.y;
    let brightness = 1.0 + variation * (hash01(in.hair) - 0.5);
    var surface: HairSurface;
    // Each hair's own shade: its brightness, and where along it the colour turns from root to tip.
    let blend = saturate(in.along + variation * (hash01(in.hair ^ 0x68e31da4u) - 0.5));
    var base = mix(shading.root_color.rgb, shading.tip_color.rgb, blend);
    if in.color.a > 0.5 {
        base = srgb_to_linear(in.color.rgb);
    }
    surface.color = base * brightness;
    surface.tangent = tangent;
    surface.normal = normal;
    surface.eye = eye;
    // Tilting the tangent by an angle shifts the highlight along the hair by the same angle.
    surface.primary_tangent = normalize(tangent * cos(shading.highlights.x) + normal * sin(shading.highlights.x));
    surface.secondary_tangent = normalize(tangent * cos(shading.highlights.y) + normal * sin(shading.highlights.y));
    surface.sparkle = 0.5 + hash01(in.hair ^ 0x9e3779b9u);
    surface.lobes = highlight_lobes(surface.primary_tangent, surface.secondary_tangent);

    let world_position = vec4(in.world_position, 1.0);
    let view_z = dot(vec4(view.view_from_world[0].z, view.view_from_world[1].z, view.view_from_world[2].z,
        view.view_from_world[3].z), world_position);
    var light_sum = vec3(0.0);

    // Directional lights, with their cascaded shadow maps.
    for (var i = 0u; i < view_bindings::lights.n_directional_lights; i = i + 1u) {
        let light = &view_bindings::lights.directional_lights[i];
        let direction = (*light).direction_to_light.xyz;
        var shadow = 1.0;
        if ((*light).flags & mesh_view_types::DIRECTIONAL_LIGHT_FLAGS_SHADOWS_ENABLED_BIT) != 0u {
            if shading.deep_shadows.x > 0.0 {
                shadow = light_through_hair(i, in.world_position, view_z, shading.deep_shadows.x);
            } else {
                shadow = shadows::fetch_directional_shadow(i, world_position, normal, view_z, in.position.xy);
            }
        }
        light_sum += shadow * shade(surface, direction, (*light).color.rgb);
    }

    // Point and spot lights of this fragment's cluster, with their shadows.
    let cluster = clustering::view_fragment_cluster_index(in.position.xy, view_z, is_orthographic());
    let ranges = clustering::unpack_clusterable_object_index_ranges(cluster);
    for (var i = ranges.first_point_light_index_offset; i < ranges.first_reflection_probe_index_offset; i = i + 1u) {
        let id = clustering::get_clusterable_object_id(i);
        let light = &view_bindings::clustered_lights.data[id];
        let to_light = (*light).position_radius.xyz - in.world_position;
        let distance_squared = dot(to_light, to_light);
        let direction = to_light * inverseSqrt(max(distance_squared, 1e-12));
        var attenuation = lighting::getDistanceAttenuation(distance_squared, (*light).color_inverse_square_range.w);
        let is_spot = i >= ranges.first_spot_light_index_offset;
        var shadow = 1.0;
        if is_spot {
            var spot_direction = vec3((*light).light_custom_data.x, 0.0, (*light).light_custom_data.y);
            spot_direction.y = sqrt(max(0.0, 1.0 - spot_direction.x * spot_direction.x - spot_direction.z * spot_direction.z));
            if ((*light).flags & mesh_view_types::POINT_LIGHT_FLAGS_SPOT_LIGHT_Y_NEGATIVE) != 0u {
                spot_direction.y = -spot_direction.y;
            }
            let cone = saturate(dot(-spot_direction, direction) * (*light).light_custom_data.z + (*light).light_custom_data.w);
            attenuation *= cone * cone;
            if ((*light).flags & mesh_view_types::POINT_LIGHT_FLAGS_SHADOWS_ENABLED_BIT) != 0u {
                shadow = shadows::fetch_spot_shadow(id, world_position, normal, (*light).shadow_map_near_z, in.position.xy);
            }
        } else if ((*light).flags & mesh_view_types::POINT_LIGHT_FLAGS_SHADOWS_ENABLED_BIT) != 0u {
            shadow = shadows::fetch_point_shadow(id, world_position, normal, in.position.xy);
        }
        light_sum += shadow * shade(surface, direction, (*light).color_inverse_square_range.rgb * attenuation);
    }

    // Ambient light, dimmer towards the roots where the hair above takes it.
    let occlusion = 1.0 - shading.parameters.w * (1.0 - in.along);
    light_sum += view_bindings::lights.ambient_color.rgb * surface.color * occlusion;

    var out: HairFragmentOutput;
    out.color = vec4(light_sum * view.exposure, 1.0);
#ifdef TONEMAP_IN_SHADER
    out.color = tone_mapping(out.color, view.color_grading);
#endif
    let covered = covered_samples(in.coverage, in.position, in.hair);
    if covered == 0u {
        discard;
    }
#ifdef MULTISAMPLED
    out.sample_mask = covered;
#endif
    return out;
}

#endif // PREPASS_PIPELINE
