//! Combed grooms and gravity preloading in the plugin: a combed groom holds its groomed shape at rest,
//! keeps the face clear, lies on the scalp when short, and falls when the head is turned over.

use std::f32::consts::FRAC_PI_2;

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::simulation::SimulatedStrand;
use hair_sim_support::headless::{hair_app, strand};

/// A head at 1.6 m with a groom on a skull ellipsoid collider of the scalp's own size.
fn groomed_head(groom: HairGroom) -> (App, Entity) {
    let mut app = hair_app();
    let skull = groom.scalp.semi_axes;
    let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    app.world_mut().spawn((HairCollider::ellipsoid(skull), HairColliderOf(head), Transform::from_xyz(0.0, 1.6, 0.0)));
    app.update();
    (app, head)
}

/// Every strand of `head`, in spawn order.
fn strands_of(app: &App, head: Entity) -> Vec<Entity> {
    app.world().get::<HeadStrands>(head).map(|strands| strands.strands().to_vec()).unwrap_or_default()
}

/// Node positions of every strand, world space.
fn shape(app: &App, strands: &[Entity]) -> Vec<Vec<Vec3>> {
    strands.iter().map(|&entity| app.world().get::<StrandNodes>(entity).unwrap().positions.clone()).collect()
}

/// RMS distance of all nodes, and of the tips, between two shapes, m.
fn rms(a: &[Vec<Vec3>], b: &[Vec<Vec3>]) -> (f32, f32) {
    let (mut all, mut count, mut tips) = (0.0, 0, 0.0);
    for (x, y) in a.iter().zip(b) {
        for (p, q) in x.iter().zip(y) {
            all += p.distance_squared(*q);
            count += 1;
        }
        tips += x.last().unwrap().distance_squared(*y.last().unwrap());
    }
    ((all / count as f32).sqrt(), (tips / a.len() as f32).sqrt())
}

/// The groomed shape and the shape after `seconds` of a groom with `preload`.
fn settle(groom: HairGroom, seconds: f32) -> (Vec<Vec<Vec3>>, Vec<Vec<Vec3>>, App, Entity) {
    let (mut app, head) = groomed_head(groom);
    app.update();
    let strands = strands_of(&app, head);
    let groomed = shape(&app, &strands);
    for _ in 0..(seconds * 60.0) as usize {
        app.update();
    }
    let settled = shape(&app, &strands);
    (groomed, settled, app, head)
}

#[test]
fn a_combed_groom_holds_its_shape_at_rest_and_half_a_preload_sags_part_of_the_way() {
    let groom = |gravity_preload| HairGroom { strand_count: 500, gravity_preload, ..default() };
    let mut errors = Vec::new();
    for preload in [1.0, 0.5, 0.0] {
        let (groomed, settled, app, _) = settle(groom(preload), 3.0);
        let statistics = app.world().resource::<HairStatistics>();
        assert_eq!(statistics.faults, 0);
        errors.push(rms(&groomed, &settled));
        println!("preload {preload}: RMS {:?} m (all nodes, tips) after 3 s", errors.last().unwrap());
    }
    let ([full, full_tips], [half, _], [none, _]) = (errors[0].into(), errors[1].into(), errors[2].into());
    assert!(full < 0.002 && full_tips < 0.005, "held within 2 mm RMS (5 mm at the tips): {full}, {full_tips}");
    assert!(none > 2.0 * full, "without preload it sags more: {none} against {full}");
    assert!(half > full && half < none, "half a preload sags part of the way: {half}");
}

/// The distance of `point` (head-local) outside the scalp ellipsoid of `groom`, m (radially, close
/// enough for points near it).
fn height_over_scalp(groom: &HairGroom, point: Vec3) -> f32 {
    let local = point - groom.scalp.centre;
    let scale = (local / groom.scalp.semi_axes).length();
    local.length() * (1.0 - 1.0 / scale)
}

#[test]
fn the_default_combed_groom_keeps_the_face_clear_at_rest() {
    let groom = HairGroom { strand_count: 1000, ..default() };
    let (_, settled, _, _) = settle(groom.clone(), 3.0);
    // The face: in front of the skull (−z), between the brow and the chin, within its width.
    let in_front = settled
        .iter()
        .flatten()
        .map(|node| *node - Vec3::new(0.0, 1.6, 0.0))
        .filter(|node| node.z < -0.04 && node.x.abs() < 0.055 && (-0.13..0.04).contains(&node.y))
        .count();
    let total: usize = settled.iter().map(Vec::len).sum();
    println!("{in_front} of {total} nodes in front of the face");
    assert_eq!(in_front, 0, "no hair hangs over the face");
    // And the hair does cover the head: nodes beside and behind it.
    assert!(settled.iter().flatten().any(|node| node.z > 0.09));
}

#[test]
fn short_combed_hair_lies_along_the_scalp() {
    let groom = HairGroom { strand_count: 600, style: HairStyle::Short, ..default() };
    let (_, settled, _, _) = settle(groom.clone(), 3.0);
    let highest = settled
        .iter()
        .flatten()
        .map(|node| height_over_scalp(&groom, *node - Vec3::new(0.0, 1.6, 0.0)))
        .fold(0.0, f32::max);
    println!("short hair at rest: highest node {:.1} mm over the scalp", 1e3 * highest);
    assert!(highest < 0.015, "within 1.5 cm of the scalp: {highest} m");
}

#[test]
fn preloaded_hair_falls_when_the_head_is_turned_upside_down() {
    let groom = HairGroom { strand_count: 300, ..default() };
    let (mut app, head) = groomed_head(groom);
    for _ in 0..60 {
        app.update();
    }
    let strands = strands_of(&app, head);
    // Turn the head over (slowly enough not to be a teleport), collider with it.
    let colliders: Vec<Entity> = app.world().get::<HeadColliders>(head).unwrap().colliders().to_vec();
    for step in 1..=60 {
        let rotation = Quat::from_rotation_z(std::f32::consts::PI * step as f32 / 60.0);
        for entity in std::iter::once(head).chain(colliders.iter().copied()) {
            app.world_mut().get_mut::<Transform>(entity).unwrap().rotation = rotation;
        }
        app.update();
    }
    for _ in 0..120 {
        app.update();
    }
    // Relative to the head, the hair now hangs the other way: its tips lie above the head's centre in
    // the head's frame, as gravity pulls them towards the head's crown.
    let rotation = Quat::from_rotation_z(std::f32::consts::PI);
    let tips_towards_crown = strands
        .iter()
        .filter(|&&entity| {
            let tip = *app.world().get::<StrandNodes>(entity).unwrap().positions.last().unwrap();
            (rotation.inverse() * (tip - Vec3::new(0.0, 1.6, 0.0))).y > 0.1
        })
        .count();
    println!("{tips_towards_crown} of {} tips beyond the crown after turning over", strands.len());
    assert!(tips_towards_crown > strands.len() / 2, "the hair falls: {tips_towards_crown}");
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
    let _ = strand(&app, strands[0]);
}

#[test]
fn combed_hair_swings_back_to_its_groomed_shape_after_the_head_shakes() {
    let (mut app, head) = groomed_head(HairGroom { strand_count: 300, ..default() });
    app.update();
    let strands = strands_of(&app, head);
    let groomed = shape(&app, &strands);
    let colliders: Vec<Entity> = app.world().get::<HeadColliders>(head).unwrap().colliders().to_vec();
    // Shaken sideways, 5 cm at 3 Hz, for a second; then still at its place for 4 s.
    let mut farthest = 0.0_f32;
    for step in 1..=(60 + 240) {
        let t = step as f32 / 60.0;
        let x = if step <= 60 { 0.05 * (std::f32::consts::TAU * 3.0 * t).sin() } else { 0.0 };
        for entity in std::iter::once(head).chain(colliders.iter().copied()) {
            app.world_mut().get_mut::<Transform>(entity).unwrap().translation.x = x;
        }
        app.update();
        if step == 45 {
            farthest = rms(&groomed, &shape(&app, &strands)).1;
        }
    }
    let settled = shape(&app, &strands);
    let (all, tips) = rms(&groomed, &settled);
    let mut offsets: Vec<f32> =
        groomed.iter().zip(&settled).map(|(a, b)| a.last().unwrap().distance(*b.last().unwrap())).collect();
    offsets.sort_by(f32::total_cmp);
    let back = offsets.iter().filter(|&&offset| offset < 0.005).count();
    println!(
        "shaking moved the tips {farthest:.4} m RMS; 4 s after, {all:.4} m RMS from the groom (tips {tips:.4} m); \
         {back} of {} tips within 5 mm of where they were groomed, median {:.4} m, worst {:.4} m",
        offsets.len(),
        offsets[offsets.len() / 2],
        offsets[offsets.len() - 1]
    );
    assert!(farthest > 0.02, "the shake moved the hair: {farthest} m");
    // Most hair swings back; strands rooted on the parting may come to rest on its other side.
    assert!(back >= offsets.len() * 3 / 4, "{back} tips back within 5 mm");
    assert!(offsets[offsets.len() / 2] < 0.002, "median tip {} m from the groom", offsets[offsets.len() / 2]);
    assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
}

/// Largest distance of a strand's nodes from `reference`, m.
fn drift(app: &App, strand: Entity, reference: &[Vec3]) -> f32 {
    let nodes = &app.world().get::<StrandNodes>(strand).unwrap().positions;
    nodes.iter().zip(reference).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max)
}

#[test]
fn a_strand_of_your_own_is_preloaded_when_built_and_again_on_demand() {
    let mut app = hair_app();
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    // 10 cm of hair held out sideways from the head, preloaded or not.
    let spawn = |app: &mut App, preload: f32| {
        let strand = HairStrand::straight(Vec3::new(0.1, 0.0, 0.0), Vec3::X, 0.1, 12).with_gravity_preload(preload);
        app.world_mut().spawn((strand, StrandOf(head))).id()
    };
    let (held, free) = (spawn(&mut app, 1.0), spawn(&mut app, 0.0));
    app.update();
    let spawned = app.world().get::<StrandNodes>(held).unwrap().positions.clone();
    for _ in 0..180 {
        app.update();
    }
    let (held_drift, free_drift) = (drift(&app, held, &spawned), drift(&app, free, &spawned));
    println!("after 3 s: preloaded {held_drift:.2e} m, not preloaded {free_drift:.4} m");
    assert!(held_drift < 1e-4 && free_drift > 0.01, "{held_drift} m, {free_drift} m");
    assert_eq!(strand(&app, held).preload_report().map(|report| report.bounded_vertices), Some(0));

    // Gravity turns sideways: the hair swings away; preloaded again where it hangs, it stays there.
    app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::new(0.0, 0.0, -9.81);
    for _ in 0..120 {
        app.update();
    }
    let swung = app.world().get::<StrandNodes>(held).unwrap().positions.clone();
    assert!(drift(&app, held, &spawned) > 0.01, "the preloaded hair responds to the new gravity");
    app.world_mut().get_mut::<SimulatedStrand>(held).unwrap().preload_gravity(1.0);
    app.update(); // preloaded under the sideways gravity, before this step
    for _ in 0..60 {
        app.update();
    }
    let still = drift(&app, held, &swung);
    app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::ZERO;
    for _ in 0..180 {
        app.update();
    }
    let relaxed = drift(&app, held, &swung);
    println!("preloaded again under sideways gravity: moved {still:.2e} m in 1 s; then weightless: {relaxed:.4} m");
    assert!(still < 1e-3, "preloaded where it hangs, it stays: {still} m");
    assert!(relaxed > 0.005, "with gravity gone, the new rest shape (which bends against it) moves the hair");
}

#[test]
fn hair_grown_over_the_shoulders_rests_on_them_where_it_was_groomed() {
    // Straight hair of 14 to 22 cm on a 10 cm skull reaches shoulders 14 cm below the skull's centre. A
    // groom grown before the shoulders were there passes through them, and the first steps throw those
    // strands out; grown with them, it drapes over them and stays.
    let groom = HairGroom { strand_count: 400, ..default() };
    let shoulders = |app: &mut App, head: Entity| {
        let across = Transform::from_xyz(0.0, 1.6 - 0.14, 0.0).with_rotation(Quat::from_rotation_z(FRAC_PI_2));
        app.world_mut().spawn((HairCollider::capsule(0.06, 0.12), across, HairColliderOf(head))).id()
    };
    let mut results = Vec::new();
    for grown_with_shoulders in [false, true] {
        let mut app = hair_app();
        let head = app.world_mut().spawn((HairHead, groom.clone(), Transform::from_xyz(0.0, 1.6, 0.0))).id();
        let skull = (HairCollider::ellipsoid(groom.scalp.semi_axes), Transform::from_xyz(0.0, 1.6, 0.0));
        app.world_mut().spawn((skull, HairColliderOf(head)));
        if grown_with_shoulders {
            shoulders(&mut app, head);
        }
        app.update();
        if !grown_with_shoulders {
            shoulders(&mut app, head);
        }
        let strands = strands_of(&app, head);
        let groomed = shape(&app, &strands);
        // Inside the shoulders, as grown (their capsule's axis runs along x at 1.46 m).
        let depth = |nodes: &[Vec<Vec3>]| {
            let axis = |node: Vec3| Vec3::new(node.x.clamp(-0.12, 0.12), 1.46, 0.0);
            nodes.iter().flatten().map(|&node| 0.06 - node.distance(axis(node))).fold(0.0_f32, f32::max)
        };
        for _ in 0..120 {
            app.update();
        }
        let settled = shape(&app, &strands);
        // How far each strand's farthest node moved.
        let moved: Vec<f32> = groomed
            .iter()
            .zip(&settled)
            .map(|(a, b)| a.iter().zip(b).map(|(p, q)| p.distance(*q)).fold(0.0_f32, f32::max))
            .collect();
        let thrown = moved.iter().filter(|&&distance| distance > 0.01).count();
        let (all, _) = rms(&groomed, &settled);
        println!(
            "grown {} the shoulders: deepest groomed node {:.1} mm inside them; after 2 s {:.2} mm RMS from the \
             groom, {thrown} of {} strands moved more than 1 cm (farthest {:.1} mm)",
            if grown_with_shoulders { "with" } else { "before" },
            1e3 * depth(&groomed),
            1e3 * all,
            strands.len(),
            1e3 * moved.iter().fold(0.0_f32, |a, &b| a.max(b)),
        );
        assert_eq!(app.world().resource::<HairStatistics>().faults, 0);
        results.push((depth(&groomed), all, thrown));
    }
    let [(through, all_through, thrown_through), (inside, all, thrown)] = results[..] else { unreachable!() };
    assert!(through > 0.02, "grown without them, the hair passes through the shoulders: {through} m deep");
    assert!(all_through > 0.01 && thrown_through > 20, "and is thrown: {all_through} m RMS, {thrown_through} strands");
    assert!(inside <= 0.0, "draped hair lies outside the shoulders: {inside} m inside");
    // Draped, it stays where it was groomed; a strand in a hundred may still buckle where it stands on them.
    assert!(all < 0.002 && thrown <= 4, "draped: {all} m RMS, {thrown} strands moved more than 1 cm");
}
