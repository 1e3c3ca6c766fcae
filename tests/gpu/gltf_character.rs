//! Hair on the shipped glTF character (`assets/models/Fox.glb`, Bevy's animated fox: modelled in
//! centimetres, spawned at a scale of 0.01, its head joint's axes its own), loaded through the asset
//! server as a game loads it and played through its walk for two seconds: every root stays on the head
//! joint where the step placed it, the hair stays within the rig's scale, nothing is rejected or faults.

use std::time::Duration;

use bevy::math::{DMat4, DVec3};
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::ColliderShape;
use bevy_hair_sim::scalp::ScalpRootBinding;
use bevy_hair_sim::simulation::{SimulatedStrand, StrandRejected};

/// The character, under the crate's `assets/`.
const FOX: &str = "models/Fox.glb";

/// The largest distance (m) of a root from where its head joint puts it at the step: the root is set from
/// the joint's pose each step, in `f64` from the joint's `f32` transform (positions near a metre, an ulp
/// 6e-8 m; the joint's matrix applied in `f32` here, a few ulps).
const ROOT_TOLERANCE: f32 = 1e-5;

/// A headless app with the renderer, stepping the hair on the CPU (the GPU's step is on by default where
/// the adapter can run it) with `settings`, one fixed step of 1/60 s per update.
fn app_on_the_cpu(settings: HairSettings) -> App {
    let mut app = App::new();
    app.add_plugins((crate::headless_renderer(), HairPlugins::default()))
        .insert_resource(HairGpuSettings { enabled: false, ..default() })
        .insert_resource(settings)
        .insert_resource(Time::<Fixed>::from_seconds(1.0 / 60.0))
        .insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(1.0 / 60.0)));
    crate::finish_adding_plugins(&mut app);
    app
}

/// Spawns the glTF scene at `path` (modelled in centimetres) at a scale of 0.01 with `hair` on it; returns
/// its root and a graph playing its clip `clip`.
fn spawn_in_centimetres(
    app: &mut App,
    path: &'static str,
    clip: usize,
    hair: HairOnCharacter,
) -> (Entity, Handle<AnimationGraph>, AnimationNodeIndex) {
    let assets = app.world().resource::<AssetServer>().clone();
    let (graph, index) = AnimationGraph::from_clip(assets.load(GltfAssetLabel::Animation(clip).from_asset(path)));
    let graph = app.world_mut().resource_mut::<Assets<AnimationGraph>>().add(graph);
    let scene = WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset(path)));
    let root = app.world_mut().spawn((scene, Transform::from_scale(Vec3::splat(0.01)), hair)).id();
    (root, graph, index)
}

#[test]
fn hair_on_the_shipped_gltf_fox_stays_on_its_head_joint_through_its_walk() {
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    let mut app = app_on_the_cpu(HairSettings::default());

    let groom =
        HairGroom { strand_count: 100, followers_per_guide: 2, segments: 12, style: HairStyle::Short, ..default() };
    let hair = HairOnCharacter::new("b_Head_05", CharacterHair::Groom(groom))
        .with_gltf_head_axes()
        .with_scalp_fitted_to_head();
    let (fox, graph, walk) = spawn_in_centimetres(&mut app, FOX, 1, hair);

    // Loaded (on the asset server's threads), spawned, the hair attached and grown.
    let mut head = None;
    for _ in 0..2000 {
        app.update();
        if let Some(HairOnCharacterStatus::Attached { head: joint }) = app.world().get::<HairOnCharacterStatus>(fox)
            && app.world().get::<HeadStrands>(*joint).is_some_and(|strands| !strands.strands().is_empty())
        {
            head = Some(*joint);
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let head = head.expect("the fox loaded and its hair grew within 2 000 frames");
    assert_eq!(app.world().get::<Name>(head).map(Name::as_str), Some("b_Head_05"));
    let scale = app.world().get::<GlobalTransform>(head).unwrap().to_scale_rotation_translation().0;
    assert!((scale - Vec3::splat(0.01)).abs().max_element() < 1e-6, "the head joint is scaled {scale}");
    // The skull fitted to the fox's head vertices (the head 25 cm across the ears, 31 cm tall to their
    // tips, 29 cm from the back of the skull to the snout; the fit takes in ears and snout, 24 × 34 × 32
    // cm): of the head's size, in metres (in the rig's centimetres it would be a hundred times larger).
    let axes = app.world().get::<HairGroom>(head).unwrap().head_axes;
    println!("the fox's head axes from its bind pose: face {}, crown {}", axes.forward, axes.up);
    // Near the joint's +X down the snout and +Y through the crown, as read off the model by eye (the
    // example's axes): the bind pose has the head pitched up 13° from them.
    let degrees = |a: Vec3, b: Vec3| a.angle_between(b).to_degrees();
    assert!(degrees(axes.forward, Vec3::X) < 15.0 && degrees(axes.up, Vec3::Y) < 15.0, "{axes:?}");
    let scalp = app.world().get::<HairGroom>(head).unwrap().scalp;
    println!("the fox's fitted skull: centre {} m, semi-axes {} m", scalp.centre, scalp.semi_axes);
    assert!(scalp.semi_axes.min_element() > 0.03 && scalp.semi_axes.max_element() < 0.2, "{}", scalp.semi_axes);

    // The walk, on the scene's animation player.
    let mut players = app.world_mut().query_filtered::<Entity, With<AnimationPlayer>>();
    let player = players.iter(app.world()).find(|&entity| {
        std::iter::successors(Some(entity), |&entity| app.world().get::<ChildOf>(entity).map(ChildOf::parent))
            .any(|ancestor| ancestor == fox)
    });
    let player = player.expect("the fox's scene has an animation player");
    app.world_mut().entity_mut(player).insert(AnimationGraphHandle(graph));
    app.world_mut().get_mut::<AnimationPlayer>(player).unwrap().play(walk).repeat();

    let strands = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    assert_eq!(strands.len(), 100);
    let first_root = app.world().get::<StrandNodes>(strands[0]).unwrap().positions[0];
    let (mut worst_root, mut farthest, mut root_travel) = (0.0_f32, 0.0_f32, 0.0_f32);
    // The joint as the animation and Bevy's propagation left it after an update: where the next update's
    // fixed step finds it (the animation moves it after the step, in `PostUpdate`).
    let mut joint = *app.world().get::<GlobalTransform>(head).unwrap();
    for _ in 0..120 {
        app.update();
        for &strand in &strands {
            assert!(app.world().get::<StrandRejected>(strand).is_none(), "strand {strand} rejected");
            let spec = app.world().get::<HairStrand>(strand).unwrap();
            let root = app.world().get::<SimulatedStrand>(strand).unwrap().rod().positions()[0].as_vec3();
            worst_root = worst_root.max(root.distance(joint.transform_point(spec.nodes[0])));
            let nodes = &app.world().get::<StrandNodes>(strand).unwrap().positions;
            farthest = nodes.iter().map(|node| node.distance(joint.translation())).fold(farthest, f32::max);
        }
        joint = *app.world().get::<GlobalTransform>(head).unwrap();
        let root = app.world().get::<StrandNodes>(strands[0]).unwrap().positions[0];
        root_travel = root_travel.max(root.distance(first_root));
    }
    let statistics = app.world().resource::<HairStatistics>();
    println!(
        "the fox's walk, 2 s: roots within {worst_root:.1e} m of the head joint's places for them, every node within {farthest:.3} m of the joint, a root travelled up to {root_travel:.2} m, {} faults",
        statistics.faults
    );
    assert!(worst_root <= ROOT_TOLERANCE, "a root is {worst_root} m from its place on the head joint");
    assert!(root_travel > 0.01, "the walk moved the head {root_travel} m: the clip did not play");
    // Short hair (5 to 8 cm) on the fitted skull, which reaches 22 cm from the joint: within half a metre
    // of it (grown in the rig's centimetres, it would be metres away).
    assert!(farthest < 0.5, "hair {farthest} m from the head joint");
    assert_eq!(statistics.faults, 0);
}

/// The humanoid made for the crate (`assets/models/Mannequin.glb`, written by `make_mannequin.py` beside
/// it): modelled in centimetres, its head joint's `+X` looking down the face.
const MANNEQUIN: &str = "models/Mannequin.glb";

/// The mannequin's skull as `make_mannequin.py` makes it, in the model's centimetres at the bind pose: an
/// ellipsoid about this centre with these semi-axes.
const MANNEQUIN_SKULL_CENTRE: Vec3 = Vec3::new(0.0, 165.5, 0.0);
const MANNEQUIN_SKULL: Vec3 = Vec3::new(7.5, 9.2, 9.7);

/// Where a root's triangle puts it: the bound corners skinned by hand (linear blend of `joint global ×
/// inverse bind pose`, as Bevy's shader skins them) from `joints`' world matrices, in double precision.
fn skinned_point(binding: &ScalpRootBinding, joints: &[DMat4]) -> DVec3 {
    let corners = binding.corners.map(|corner| -> DVec3 {
        (0..4)
            .map(|k| {
                f64::from(corner.weights[k])
                    * joints[usize::from(corner.joints[k])].transform_point3(corner.position.as_dvec3())
            })
            .sum()
    });
    let weights = binding.barycentric;
    weights.x * corners[0] + weights.y * corners[1] + weights.z * corners[2]
}

#[test]
fn hair_on_the_shipped_gltf_mannequin_grows_on_its_scalp_with_no_numbers_given_and_stays_on_it() {
    let _renderer = hair_sim_support::renderer::one_at_a_time();
    let mut app = app_on_the_cpu(HairSettings::styled());

    // As the crate guide puts hair on a glTF character: names, and nothing measured by hand.
    let groom = HairGroom { strand_count: 150, followers_per_guide: 2, ..default() };
    let hair = HairOnCharacter::new("Head", CharacterHair::Groom(groom))
        .with_gltf_head_axes()
        .with_scalp_fitted_to_head()
        .with_scalp_mesh("Scalp")
        .with_collider_meshes(["Face"]);
    let (character, graph, look_around) = spawn_in_centimetres(&mut app, MANNEQUIN, 2, hair);
    let mut head = None;
    for _ in 0..2000 {
        app.update();
        // The face baked (on the async pool): the strands wait for it before their first step.
        let face_baked = app
            .world_mut()
            .query::<&HairCollider>()
            .iter(app.world())
            .any(|collider| matches!(collider.shape, ColliderShape::Mesh { .. }));
        if let Some(&HairOnCharacterStatus::Attached { head: joint }) =
            app.world().get::<HairOnCharacterStatus>(character)
            && app.world().get::<HeadStrands>(joint).is_some_and(|strands| !strands.strands().is_empty())
            && face_baked
        {
            head = Some(joint);
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let head = head.expect("the mannequin loaded, its hair grew and its face baked within 2 000 frames");

    // Its axes read off the bind pose: the joint's +X down the face and +Y up, as the model was made
    // (to the f32 rounding of the quaternion written in the file).
    let axes = app.world().get::<HairGroom>(head).unwrap().head_axes;
    assert!(axes.forward.distance(Vec3::X) < 1e-5 && axes.up.distance(Vec3::Y) < 1e-5, "{axes:?}");
    // The skull fitted to the head's vertices (its cranium, ears, nose, eyes and the jaw's upper half):
    // each semi-axis within 15 % of the cranium's, in metres.
    let fitted = app.world().get::<HairGroom>(head).unwrap().scalp;
    println!("the mannequin's fitted skull: centre {} m, semi-axes {} m", fitted.centre, fitted.semi_axes);
    let cranium = MANNEQUIN_SKULL * 0.01;
    assert!(
        ((fitted.semi_axes - cranium) / cranium).abs().max_element() < 0.15,
        "{} against {cranium}",
        fitted.semi_axes
    );

    // The look-around clip on the scene's animation player.
    let mut players = app.world_mut().query_filtered::<Entity, With<AnimationPlayer>>();
    let player = players.iter(app.world()).next().expect("the mannequin's scene has an animation player");
    app.world_mut().entity_mut(player).insert(AnimationGraphHandle(graph));
    app.world_mut().get_mut::<AnimationPlayer>(player).unwrap().play(look_around).repeat();

    let strands = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    assert_eq!(strands.len(), 150);
    let scalp = app.world().get::<ScalpRootBinding>(strands[0]).expect("roots bound to the scalp").mesh;
    let skin = app.world().get::<SkinnedMesh>(scalp).unwrap().clone();
    let inverse_binds =
        app.world().resource::<Assets<SkinnedMeshInverseBindposes>>().get(&skin.inverse_bindposes).unwrap().to_vec();
    let head_index = skin.joints.iter().position(|&joint| joint == head).unwrap();
    let joint_matrices = |app: &App| -> Vec<DMat4> {
        skin.joints
            .iter()
            .zip(&inverse_binds)
            .map(|(&joint, inverse_bind)| {
                app.world().get::<GlobalTransform>(joint).unwrap().to_matrix().as_dmat4() * inverse_bind.as_dmat4()
            })
            .collect()
    };
    let (mut worst_root, mut deepest, mut farthest, mut turned) = (0.0_f64, 0.0_f32, 0.0_f32, 0.0_f32);
    let start = app.world().get::<GlobalTransform>(head).unwrap().rotation();
    // The joints as the animation and propagation left them after an update: where the next update's
    // fixed step finds them.
    let mut joints = joint_matrices(&app);
    for _ in 0..120 {
        app.update();
        // From world to the model's centimetres at the bind pose, through the head joint.
        let to_model = joints[head_index].inverse();
        let joint_place = app.world().get::<GlobalTransform>(head).unwrap().translation();
        for &strand in &strands {
            assert!(app.world().get::<StrandRejected>(strand).is_none(), "strand {strand} rejected");
            let binding = app.world().get::<ScalpRootBinding>(strand).expect("every root bound to the scalp");
            let root = app.world().get::<SimulatedStrand>(strand).unwrap().rod().positions()[0];
            worst_root = worst_root.max(root.distance(skinned_point(binding, &joints)));
            for &node in &app.world().get::<StrandNodes>(strand).unwrap().positions {
                let model = to_model.transform_point3(node.as_dvec3()).as_vec3();
                // Depth inside the cranium, m, to first order: (1 − |x/a|) times the semi-axis along x.
                let radial = ((model - MANNEQUIN_SKULL_CENTRE) / MANNEQUIN_SKULL).length();
                let along = (model - MANNEQUIN_SKULL_CENTRE).length() / radial.max(1e-6);
                deepest = deepest.max((1.0 - radial) * along * 0.01);
                farthest = farthest.max(node.distance(joint_place));
            }
        }
        joints = joint_matrices(&app);
        turned = turned.max(app.world().get::<GlobalTransform>(head).unwrap().rotation().angle_between(start));
    }
    let statistics = app.world().resource::<HairStatistics>();
    println!(
        "the mannequin looking around, 2 s: roots within {worst_root:.1e} m of their skinned triangles' points, deepest node {deepest:.1e} m inside the cranium, every node within {farthest:.3} m of the head joint, the head turned up to {turned:.2} rad, {} faults",
        statistics.faults
    );
    assert!(worst_root <= f64::from(ROOT_TOLERANCE), "a root is {worst_root} m from its skinned point");
    assert!(turned > 0.5, "the head turned {turned} rad: the clip did not play");
    // The face's collider holds the hair out of the head: no node more than 1 mm inside the cranium.
    assert!(deepest <= 1e-3, "a node {deepest} m inside the cranium");
    // Hair of up to 30 cm on a 10 cm head: within half a metre of the joint.
    assert!(farthest < 0.5, "hair {farthest} m from the head joint");
    assert_eq!(statistics.faults, 0);
}
