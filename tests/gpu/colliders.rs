//! Hair dropped on each collider shape the plugin has (sphere, capsule, ellipsoid, plane, box, rounded box,
//! baked mesh), stepped on the GPU and on the CPU from the same state for 15 s: how deep any node or point
//! of an edge lies inside the shape, and where the hair rests, how far the GPU's is from the CPU's.

use bevy::math::{DQuat, DVec3};
use bevy::platform::sync::Arc;
use bevy_hair_sim::gpu::{GpuHeadStep, GpuStrandInput, GpuStrandSolver};
use bevy_hair_sim::rod::{
    ColliderShape, Contacts, DistanceField, MovingCollider, RigidPose, Rod, RodMaterial, RodWorkspace, StepParams,
};
use hair_sim_support::{star_shaped, straight_nodes};

use crate::step::device;

/// The head the strands hang from, away from the origin (the GPU holds positions relative to it).
const HEAD: DVec3 = DVec3::new(0.3, 1.6, -0.2);
/// Strands, their length (m) and edges (1 cm each), and the hair's collision thickness (m).
const STRANDS: usize = 3;
const LENGTH: f64 = 0.24;
const EDGES: usize = 24;
const THICKNESS: f64 = 1e-4;
/// Steps of 1/60 s until the hair rests (15 s, with air drag).
const STEPS: usize = 900;

/// Three strands rooted in a row 2 cm long across X at the head's origin, each leaving it horizontally
/// along +Z, with human hair's material: they fall across whatever lies below and hang over its +Z side.
fn strands() -> Vec<Rod> {
    (0..STRANDS)
        .map(|k| {
            let root = HEAD + DVec3::new(0.01 * (k as f64 - 1.0), 0.0, 0.0);
            let nodes: Vec<DVec3> = straight_nodes(LENGTH, EDGES, DVec3::Z).into_iter().map(|p| p + root).collect();
            let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
            rod.clamp_root_in_place();
            rod
        })
        .collect()
}

/// The signed distance from `point` to `collider`'s shape grown by the hair's thickness, m (negative
/// inside): the shape's distance bound, which for a point inside an ellipsoid overstates the depth.
fn distance(collider: &MovingCollider, point: DVec3) -> f64 {
    let local = collider.end.to_local(point);
    match collider.shape {
        ColliderShape::Plane => local.y - THICKNESS,
        ref shape => shape.inflated(THICKNESS).distance_bound(local),
    }
}

/// How deep `point` lies inside `collider` grown by the hair's thickness, m (0 outside).
fn depth(collider: &MovingCollider, point: DVec3) -> f64 {
    (-distance(collider, point)).max(0.0)
}

/// How near `nodes` come to `collider`'s surface at a node or at one of nine points along each edge, m (0
/// where they reach inside).
fn nearest(collider: &MovingCollider, nodes: &[DVec3]) -> f64 {
    along_strand(nodes).map(|p| distance(collider, p).max(0.0)).fold(f64::INFINITY, f64::min)
}

/// The nodes, and nine points along each edge.
fn along_strand(nodes: &[DVec3]) -> impl Iterator<Item = DVec3> + '_ {
    let along_edges = nodes.windows(2).flat_map(|edge| (1..10).map(move |k| edge[0].lerp(edge[1], k as f64 / 10.0)));
    nodes.iter().copied().chain(along_edges)
}

/// The deepest any node or any point of an edge (nine along each) lies inside `collider`, m.
fn deepest(collider: &MovingCollider, nodes: &[DVec3]) -> f64 {
    along_strand(nodes).map(|p| depth(collider, p)).fold(0.0, f64::max)
}

/// A ball of `radius` m with a groove around its equator (10 % deep) and a bump on top, as a closed
/// triangle mesh of `rings` rings: not convex, so its contact is the baked field's.
fn grooved_ball(radius: f64, rings: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let shape = |direction: DVec3| {
        let polar = direction.y.clamp(-1.0, 1.0).acos();
        let groove = 0.1 * (-((polar - std::f64::consts::FRAC_PI_2) / 0.25).powi(2)).exp();
        let bump = 0.15 * (-(polar / 0.4).powi(2)).exp();
        radius * (1.0 - groove + bump)
    };
    star_shaped(shape, rings)
}

/// What a scene's hair does after `STEPS`.
#[derive(Clone, Copy, PartialEq)]
enum Outcome {
    /// It rests on the GPU (no node faster than 1 mm/s), within `APART` RMS of the CPU's.
    Rests,
    /// It keeps moving on both (hair slipping to and fro over a sharp edge, or over the facets of a coarse
    /// field): only how deep it lies is checked.
    KeepsMoving,
}

/// Drops the strands on `shape` placed at `rotation` and `offset` from the head, with no friction (so
/// that where they rest is set by the shape alone, not by where they landed), and steps them `STEPS` on the
/// GPU and on the CPU: no fault, every node and edge of both at most `INSIDE` inside the shape at every
/// second, the hair lying on it, and at the end the `outcome`.
fn drop_on(name: &str, shape: ColliderShape, rotation: DQuat, offset: DVec3, outcome: Outcome) {
    let (_turn, device, queue) = device();
    let at = RigidPose { rotation, translation: HEAD + offset };
    let collider = MovingCollider { shape, friction: 0.0, start: at, end: at };
    let mut rods = strands();
    let params = StepParams { dt: 1.0 / 60.0, air_damping: 5.0, ..Default::default() };
    let inputs: Vec<GpuStrandInput> = rods
        .iter()
        .map(|rod| GpuStrandInput {
            rod,
            head: 0,
            thickness: THICKNESS,
            groomed: None,
            hairs: 1.0,
            groomed_fractions: None,
        })
        .collect();
    let mut gpu = GpuStrandSolver::new(&device, &inputs, &[(DQuat::IDENTITY, HEAD)]).unwrap();
    let head = GpuHeadStep { translation: HEAD, colliders: vec![collider.clone()], ..Default::default() };
    let contacts = Contacts { colliders: std::slice::from_ref(&collider), thickness: THICKNESS };
    let mut workspace = RodWorkspace::default();
    let (mut gpu_inside, mut cpu_inside) = (0.0_f64, 0.0_f64);
    for step in 1..=STEPS {
        gpu.step(&device, &queue, &params, std::slice::from_ref(&head)).unwrap();
        for rod in &mut rods {
            rod.step_with_contacts(&params, None, &contacts, &mut workspace).unwrap();
        }
        if step % 60 == 0 {
            let states = gpu.read_back(&device, &queue);
            for (s, rod) in rods.iter().enumerate() {
                assert!(states.status[s].faults == 0, "{name}: {:?}", states.status[s]);
                gpu_inside = gpu_inside.max(deepest(&collider, &states.positions[s]));
                cpu_inside = cpu_inside.max(deepest(&collider, rod.positions()));
            }
        }
    }
    let states = gpu.read_back(&device, &queue);
    let fastest = |velocities: &[Vec<DVec3>]| velocities.iter().flatten().map(|v| v.length()).fold(0.0, f64::max);
    let cpu: Vec<Vec<DVec3>> = rods.iter().map(|rod| rod.positions().to_vec()).collect();
    let cpu_velocities: Vec<Vec<DVec3>> = rods.iter().map(|rod| rod.velocities().to_vec()).collect();
    let (gpu_speed, cpu_speed) = (fastest(&states.velocities), fastest(&cpu_velocities));
    // How far the strand furthest from the shape comes to it, at a node or along an edge.
    let aloof = states.positions.iter().map(|nodes| nearest(&collider, nodes)).fold(0.0, f64::max);
    let (rms, largest) = apart(&states.positions, &cpu);
    println!(
        "{name}: deepest inside at each second, GPU {gpu_inside:.2e} m, CPU {cpu_inside:.2e} m; every GPU strand comes \
         within {aloof:.1e} m of it; after {} s the fastest node moves {gpu_speed:.1e} m/s on the GPU, \
         {cpu_speed:.1e} on the CPU; GPU − CPU nodes: RMS {rms:.2e} m, largest {largest:.2e} m",
        STEPS / 60
    );
    assert!(gpu_inside <= INSIDE, "{name}: a GPU node or edge lies {gpu_inside:e} m inside");
    assert!(cpu_inside <= INSIDE, "{name}: a CPU node or edge lies {cpu_inside:e} m inside");
    assert!(aloof < 1e-3, "{name}: a strand comes no nearer than {aloof:e} m to the shape");
    if let Outcome::Rests = outcome {
        assert!(gpu_speed < 1e-3, "{name}: the GPU's hair still moves at {gpu_speed} m/s");
        assert!(rms <= APART, "{name}: the GPU's hair rests {rms:e} m RMS from the CPU's (bound {APART:e} m)");
    }
}

/// The deepest a node or a point of an edge may lie inside a collider grown by the hair's thickness, m: the
/// hair's centre line at most a millimetre into a face, a shoulder, a hat.
const INSIDE: f64 = 1e-3;

/// How far the GPU's resting hair may be from the CPU's, RMS over the nodes, m. Not single precision's
/// bound: without contact the two steps settle within `2 ε N L √N` of each other (`tests/gpu/step.rs`,
/// 3e-6 m here), but their contact models settle on different fixed points: the CPU's springs act inside
/// its solve, whose iterations go on until the set of touching nodes holds, and it pushes out edges edge
/// after edge; the GPU takes two Newton iterations, puts what ended inside on the surface after them, and
/// pushes edges out all at once along each node's normal. Measured 0.045 mm on a plane, 0.9 mm on a
/// sphere, an ellipsoid and a capsule, 1.8 mm on the mesh, 3.9 mm on the rounded box (where one strand
/// lies across its rounded edge on a single node): a few millimetres, which no picture of a head shows.
const APART: f64 = 5e-3;

/// RMS and largest distance between the GPU's and the CPU's nodes, m.
pub(crate) fn apart(gpu: &[Vec<DVec3>], cpu: &[Vec<DVec3>]) -> (f64, f64) {
    let distances: Vec<f64> = gpu.iter().flatten().zip(cpu.iter().flatten()).map(|(a, b)| a.distance(*b)).collect();
    let rms = (distances.iter().map(|d| d * d).sum::<f64>() / distances.len() as f64).sqrt();
    (rms, distances.iter().copied().fold(0.0, f64::max))
}

#[test]
fn hair_rests_on_a_sphere_as_on_the_cpu() {
    drop_on("sphere", ColliderShape::sphere(0.1), DQuat::IDENTITY, DVec3::new(0.0, -0.13, 0.0), Outcome::Rests);
}

#[test]
fn hair_rests_on_a_capsule_as_on_the_cpu() {
    let lying = DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2);
    drop_on("capsule", ColliderShape::capsule(0.05, 0.1), lying, DVec3::new(0.0, -0.08, 0.0), Outcome::Rests);
}

#[test]
fn hair_rests_on_an_ellipsoid_as_on_the_cpu() {
    let tilted = DQuat::from_rotation_x(0.3);
    drop_on(
        "ellipsoid",
        ColliderShape::ellipsoid(DVec3::new(0.12, 0.08, 0.1)),
        tilted,
        DVec3::new(0.0, -0.11, 0.0),
        Outcome::Rests,
    );
}

#[test]
fn hair_rests_on_a_plane_as_on_the_cpu() {
    drop_on("plane", ColliderShape::Plane, DQuat::IDENTITY, DVec3::new(0.0, -0.1, 0.0), Outcome::Rests);
}

/// A sharp box: hair over its edge slips to and fro there on the CPU and on the GPU alike (the fastest node
/// still at 0.3 m/s on the CPU after 15 s, 1.6 cm/s on the GPU), so only its depth is checked.
#[test]
fn hair_over_a_box_edge_stays_outside_it() {
    drop_on(
        "box",
        ColliderShape::cuboid(DVec3::new(0.1, 0.06, 0.1)),
        DQuat::IDENTITY,
        DVec3::new(0.0, -0.09, 0.0),
        Outcome::KeepsMoving,
    );
}

#[test]
fn hair_rests_on_a_rounded_box_as_on_the_cpu() {
    let shape = ColliderShape::Cuboid { half_extents: DVec3::new(0.08, 0.04, 0.08), rounding: 0.02 };
    drop_on("rounded box", shape, DQuat::from_rotation_x(0.3), DVec3::new(0.0, -0.09, 0.0), Outcome::Rests);
}

/// A grooved ball baked at 4 mm cells (not convex): the hair rests on the GPU, while on the CPU the
/// trilinear field's facets keep it creeping (6 cm/s after 15 s).
#[test]
fn hair_rests_on_a_baked_mesh_as_on_the_cpu() {
    let (positions, triangles) = grooved_ball(0.1, 24);
    let field = DistanceField::bake(&positions, &triangles, 0.004).unwrap();
    let shape = ColliderShape::mesh(Arc::new(field));
    drop_on("mesh", shape, DQuat::IDENTITY, DVec3::new(0.0, -0.15, 0.0), Outcome::Rests);
}

/// A free strand (nothing holds it) dropped flat from 3 cm onto a floor: every node lands, its first two
/// too (a held strand's are never tested against colliders), and it rests on the floor as on the CPU: no
/// node deeper than [`INSIDE`] ever, each node on the floor grown by the strand's thickness to within that
/// after a second, and the strand within [`APART`] of where the CPU's lies (measured 0.13 mm).
#[test]
fn a_free_strand_dropped_on_a_floor_rests_on_it_as_on_the_cpu() {
    let (_turn, device, queue) = device();
    let floor = DVec3::new(0.2, 0.9, -0.1);
    let thickness = 1e-4;
    // 12 cm in 24 edges, 3 cm above the floor, a little bent so that it lands unevenly.
    let nodes: Vec<DVec3> = (0..=24)
        .map(|k| {
            let s = k as f64 / 24.0;
            floor + DVec3::new(0.12 * s, 0.03 + 0.01 * s * s, 0.01 * (3.0 * s).sin())
        })
        .collect();
    let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair()).unwrap();
    let at = RigidPose { rotation: DQuat::IDENTITY, translation: floor };
    let plane = MovingCollider { shape: ColliderShape::Plane, friction: 0.3, start: at, end: at };
    let input = GpuStrandInput { rod: &rod, head: 0, thickness, groomed: None, hairs: 1.0, groomed_fractions: None };
    let mut gpu = GpuStrandSolver::new(&device, &[input], &[(DQuat::IDENTITY, floor)]).unwrap();
    let head = GpuHeadStep { translation: floor, colliders: vec![plane.clone()], ..Default::default() };
    let params = StepParams::default();
    let contacts = Contacts { colliders: std::slice::from_ref(&plane), thickness };
    let mut workspace = RodWorkspace::default();
    let mut deepest = 0.0_f64;
    for step in 1..=60 {
        gpu.step(&device, &queue, &params, std::slice::from_ref(&head)).unwrap();
        rod.step_with_contacts(&params, None, &contacts, &mut workspace).unwrap();
        let states = gpu.read_back(&device, &queue);
        assert!(states.status[0].fault.is_none(), "step {step}: {:?}", states.status[0]);
        let depth = states.positions[0].iter().map(|p| floor.y + thickness - p.y).fold(f64::MIN, f64::max);
        deepest = deepest.max(depth);
    }
    let states = gpu.read_back(&device, &queue);
    let (gpu_nodes, cpu_nodes) = (&states.positions[0], rod.positions());
    let heights: Vec<f64> = gpu_nodes.iter().map(|p| p.y - floor.y - thickness).collect();
    let rms = (gpu_nodes.iter().zip(cpu_nodes).map(|(g, c)| g.distance_squared(*c)).sum::<f64>()
        / gpu_nodes.len() as f64)
        .sqrt();
    println!(
        "after 1 s: heights above the grown floor {:.2e} … {:.2e} m (deepest ever {deepest:.2e} m inside), {} nodes touching; GPU − CPU {rms:.2e} m RMS",
        heights.iter().copied().fold(f64::INFINITY, f64::min),
        heights.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        states.status[0].contacts
    );
    assert!(deepest <= INSIDE, "a node {deepest} m inside the floor");
    assert!(heights[..2].iter().all(|h| h.abs() < INSIDE), "the free root landed: heights {:?}", &heights[..2]);
    assert!(heights.iter().all(|h| h.abs() < INSIDE), "the strand lies on the floor: {heights:?}");
    assert!(rms <= APART, "the GPU's strand {rms} m RMS from the CPU's");
}
