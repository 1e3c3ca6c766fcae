//! The `character` example's character (built in code as a glTF importer spawns one, shared with the
//! example through `examples/support/character_in_code.rs`) with the example's groom and settings, its
//! hair stepped on the GPU (and, as a game without one steps it, on the CPU) while the neck sways and the
//! head turns: every guide on the path asked for, no fault, and the face's mesh collider (baked from the
//! `Face` mesh) holding the hair, no node deeper than 1 mm inside it.

use bevy::ecs::system::RunSystemOnce;
use bevy::mesh::skinning::SkinnedMeshInverseBindposes;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::ColliderShape;
use bevy_hair_sim::simulation::{SimulatedStrand, SteppedElsewhere};

#[path = "../../examples/support/character_in_code.rs"]
#[allow(dead_code)]
mod character_in_code;
use character_in_code::{Joint, scalp_groom, spawn_character_in_code, swayed};

/// Fixed step, s.
const DT: f64 = 1.0 / 60.0;
/// The deepest a node may lie inside the face (its baked mesh), m: the bound for hair resting on
/// a collider.
const DEEPEST: f64 = 1e-3;
/// Steps of swaying before the first look at the hair: the groom is grown along the skull's ellipsoid,
/// through the tops of the ears, and the first steps put it outside them.
const SETTLING_STEPS: usize = 60;
/// Steps of swaying between looks at the hair, and how many looks (3 s in all).
const STEPS_BETWEEN_LOOKS: usize = 30;
const LOOKS: usize = 6;

/// The app as the example makes it (the styled look, the GPU by default, or the CPU where `gpu` is
/// false), headless, one fixed step an update, the character spawned with the example's straight groom.
fn app(gpu: bool) -> (App, Entity) {
    let mut app = App::new();
    app.add_plugins((crate::headless_renderer(), HairPlugins::default()))
        .insert_resource(HairGpuSettings { enabled: gpu, ..default() })
        .insert_resource(HairSettings::styled())
        .insert_resource(Time::<Fixed>::from_seconds(DT))
        .insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    crate::finish_adding_plugins(&mut app);
    let root = app
        .world_mut()
        .run_system_once(
            |mut commands: Commands,
             mut meshes: ResMut<Assets<Mesh>>,
             mut materials: ResMut<Assets<StandardMaterial>>,
             mut bindposes: ResMut<Assets<SkinnedMeshInverseBindposes>>| {
                let hair = CharacterHair::Groom(scalp_groom(HairStyle::Straight));
                spawn_character_in_code(&mut commands, &mut meshes, &mut materials, &mut bindposes, hair)
            },
        )
        .expect("the character spawns");
    (app, root)
}

/// Sets the joints to their sway at `step` and runs one update.
fn sway(app: &mut App, step: usize) {
    let mut joints = app.world_mut().query::<(&Joint, &mut Transform)>();
    for (joint, mut transform) in joints.iter_mut(app.world_mut()) {
        *transform = swayed(joint, step as f32 * DT as f32);
    }
    app.update();
}

#[test]
fn the_character_example_s_face_holds_its_hair_on_the_gpu() {
    face_holds_the_hair(true);
}

/// The same on the CPU's step (a game whose adapter cannot step hair, WebGL2). With 4 rounds of contact
/// (push out, project lengths) at most, the CPU left nodes up to 3.4 mm inside the ears where they meet
/// the skull (concave); with 16, none inside.
#[test]
fn the_character_example_s_face_holds_its_hair_on_the_cpu() {
    face_holds_the_hair(false);
}

/// The character swayed, its hair stepped on the GPU or (`gpu` false) on the CPU, looked at [`LOOKS`]
/// times: the assertions of the module's documentation.
fn face_holds_the_hair(gpu: bool) {
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    let (mut app, root) = app(gpu);
    // Attached, grown, the face baked (on the async pool) and every guide built, on the GPU where asked.
    let mut head = None;
    for _ in 0..3000 {
        app.update();
        if let Some(&HairOnCharacterStatus::Attached { head: joint }) = app.world().get::<HairOnCharacterStatus>(root)
            && let Some(strands) = app.world().get::<HeadStrands>(joint)
            && !strands.strands().is_empty()
            && strands.strands().iter().all(|&strand| {
                app.world().get::<SimulatedStrand>(strand).is_some()
                    && app.world().get::<SteppedElsewhere>(strand).is_some() == gpu
            })
            && app
                .world_mut()
                .query::<&HairCollider>()
                .iter(app.world())
                .any(|c| matches!(c.shape, ColliderShape::Mesh { .. }))
        {
            head = Some(joint);
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let head = head.expect(
        "the hair attached, every guide built (on the GPU where asked) and the face baked within 3 000 updates",
    );
    let guides = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    let mut faces = app.world_mut().query::<(Entity, &HairCollider, &HairColliderOf)>();
    let face: Vec<(Entity, ColliderShape)> = faces
        .iter(app.world())
        .filter(|(_, collider, of)| of.0 == head && matches!(collider.shape, ColliderShape::Mesh { .. }))
        .map(|(entity, collider, _)| (entity, collider.shape.clone()))
        .collect();
    let [(face, face_shape)] = face.as_slice() else { panic!("one mesh collider, the face's: {}", face.len()) };
    let margin = app.world().resource::<HairSettings>().collision_margin;

    let (mut deepest, mut deepest_grown, mut deepest_root, mut near) = (0.0_f64, 0.0_f64, 0.0_f64, 0_usize);
    let mut step = 0;
    for look in 0..LOOKS {
        app.world_mut().resource_mut::<HairPause>().paused = false;
        let steps = if look == 0 { SETTLING_STEPS } else { STEPS_BETWEEN_LOOKS };
        for _ in 0..steps {
            step += 1;
            sway(&mut app, step);
        }
        // The joints held for one more step, so that the face's pose after it is the one the step met;
        // then (on the GPU) paused until the state after that step is read back.
        let (contacts, given_up) = if gpu {
            app.world_mut().resource_mut::<HairGpuSettings>().read_back_now = true;
            app.update();
            app.world_mut().resource_mut::<HairPause>().paused = true;
            let mut arrived = false;
            for _ in 0..60 {
                app.update();
                if app.world().resource::<HairGpuStatus>().read_back_age == Some(0) {
                    arrived = true;
                    break;
                }
            }
            let status = app.world().resource::<HairGpuStatus>().clone();
            assert!(arrived, "the state was not read back: {status:?}");
            assert_eq!(status.error, None);
            assert_eq!(
                (status.strands, status.faults),
                (guides.len(), 0),
                "every guide on the GPU, no fault: {status:?}"
            );
            (status.contacts, status.contact_given_up)
        } else {
            app.update();
            let statistics = app.world().resource::<HairStatistics>();
            assert_eq!((statistics.strands, statistics.faults), (guides.len(), 0), "every guide stepped, no fault");
            (statistics.contacts, 0)
        };
        assert!(guides.iter().all(|&guide| app.world().get::<SteppedElsewhere>(guide).is_some() == gpu));

        let pose = app.world().get::<GlobalTransform>(*face).unwrap().compute_transform();
        let local = |p: Vec3| pose.rotation.inverse().mul_vec3(p - pose.translation).as_dvec3();
        let (mut look_deepest, mut look_near) = (0.0_f64, 0);
        for &guide in &guides {
            let nodes = &app.world().get::<StrandNodes>(guide).unwrap().positions;
            let thickness = f64::from(app.world().get::<SimulatedStrand>(guide).unwrap().collision_thickness(margin));
            let grown = face_shape.inflated(thickness);
            deepest_root = deepest_root.max(-face_shape.distance_bound(local(nodes[0])));
            // Past the root edge (prescribed on the scalp).
            for &node in &nodes[2..] {
                let depth = -face_shape.distance_bound(local(node));
                look_deepest = look_deepest.max(depth);
                deepest_grown = deepest_grown.max(-grown.distance_bound(local(node)));
                look_near += usize::from(depth > -2.0 * thickness);
            }
        }
        println!(
            "look {look} (step {step}): the deepest node {look_deepest:.2e} m inside the face, {look_near} nodes within twice a strand's thickness of it; {contacts} in contact, {given_up} strands' contact given up (on the GPU)"
        );
        deepest = deepest.max(look_deepest);
        near += look_near;
    }
    println!(
        "{} guides on the {}, looked at {LOOKS} times over steps {SETTLING_STEPS} to {step}: the deepest node {deepest:.2e} m inside the face ({deepest_grown:.2e} m inside it grown by the strands' thickness), the deepest root {deepest_root:.2e} m",
        guides.len(),
        if gpu { "GPU" } else { "CPU" }
    );
    assert!(near > 0, "no hair comes near the face: the test does not reach the case");
    assert!(deepest <= DEEPEST, "a node lies {deepest} m inside the face");
}
