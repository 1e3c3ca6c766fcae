//! Follower hairs: placed from their guide's motion in the guide's material frames, with roots of their
//! own spread evenly over the scalp, kept out of the head.

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use hair_sim_support::headless::hair_app;

/// Every follower node of every guide of `head`, world space.
fn follower_nodes(app: &App, head: Entity) -> Vec<Vec3> {
    let guides = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    guides.iter().flat_map(|&guide| app.world().get::<FollowerNodes>(guide).unwrap().positions.clone()).collect()
}

/// A weightless head at 1.6 m with an uncombed groom of `guides` guides and `followers` followers each,
/// neither clumped nor scattered.
fn weightless_head(guides: usize, followers: usize) -> (App, Entity, HairGroom) {
    let mut app = hair_app();
    app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::ZERO;
    let groom = HairGroom {
        strand_count: guides,
        followers_per_guide: followers,
        segments: 12,
        style: HairStyle::Curly,
        combing: None,
        gravity_preload: 0.0,
        // Each follower exactly its own curve, moved with its guide.
        follower_clumping: 0.0,
        follower_scatter: 0.0,
        ..default()
    };
    let head = app.world_mut().spawn((HairHead, groom.clone(), Transform::from_xyz(0.0, 1.6, 0.0))).id();
    app.update();
    app.update();
    (app, head, groom)
}

#[test]
fn followers_reproduce_their_rest_shapes_and_move_rigidly_with_the_head() {
    let (mut app, head, _) = weightless_head(40, 8);
    let guides = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    // At rest, every follower node is where its curve puts it, carried to the head's place.
    let mut worst = 0.0_f32;
    for &guide in &guides {
        let curves = &app.world().get::<HairFollowers>(guide).unwrap().curves;
        let placed = app.world().get::<FollowerNodes>(guide).unwrap();
        assert_eq!(placed.count(), curves.len());
        for (index, curve) in curves.iter().enumerate() {
            for (node, rest) in placed.follower(index).iter().zip(curve) {
                worst = worst.max(node.distance(*rest + Vec3::new(0.0, 1.6, 0.0)));
            }
        }
    }
    let total: usize = guides.iter().map(|&g| app.world().get::<FollowerNodes>(g).unwrap().count()).sum();
    println!("{total} followers at rest within {worst:.2e} m of their rest shapes");
    assert_eq!(total, 40 * 8);
    assert_eq!(app.world().resource::<HairStatistics>().followers, 320);
    assert!(worst < 1e-6, "{worst} m");

    // Moved 3 m and turned 1 rad in one step (a teleport: the hair is carried rigidly).
    let before = follower_nodes(&app, head);
    let (old, new) = (
        Transform::from_xyz(0.0, 1.6, 0.0),
        Transform::from_xyz(3.0, 1.2, -1.0).with_rotation(Quat::from_euler(EulerRot::YXZ, 1.0, 0.3, -0.2)),
    );
    *app.world_mut().get_mut::<Transform>(head).unwrap() = new;
    app.update();
    let after = follower_nodes(&app, head);
    let carried = before.iter().map(|&p| new.transform_point(old.compute_affine().inverse().transform_point3(p)));
    let worst = after.iter().zip(carried).map(|(a, b)| a.distance(b)).fold(0.0_f32, f32::max);
    println!("after the head moved 3 m and turned: every follower node within {worst:.2e} m of where it was carried");
    assert!(worst < 1e-5, "{worst} m");
}

#[test]
fn a_twisted_guide_turns_its_followers_around_it_by_the_same_angle() {
    let mut app = hair_app();
    app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::ZERO;
    let head = app.world_mut().spawn((HairHead, Transform::default())).id();
    // A straight 10 cm guide along +x with a follower 5 mm beside it along +y.
    let guide = HairStrand::straight(Vec3::ZERO, Vec3::X, 0.1, 10);
    let follower: Vec<Vec3> = guide.nodes.iter().map(|node| *node + Vec3::Y * 0.005).collect();
    let entity =
        app.world_mut().spawn((guide, HairFollowers { curves: vec![follower], ..default() }, StrandOf(head))).id();
    app.update();
    // A rest twist of 0.1 rad at every vertex turns the tip's edge by 0.9 rad about the strand.
    for twist in &mut app.world_mut().get_mut::<StrandRestShape>(entity).unwrap().twists[1..10] {
        *twist = 0.1;
    }
    for _ in 0..600 {
        app.update();
    }
    let frames = app.world().get::<StrandFrames>(entity).unwrap();
    let tip_frame = frames.material_frame(9).unwrap();
    let guide_turn = tip_frame.m1.angle_between(app.world().get::<StrandFrames>(entity).map(|_| Vec3::Y).unwrap());
    let tip = app.world().get::<StrandNodes>(entity).unwrap().positions[10];
    let follower_tip = app.world().get::<FollowerNodes>(entity).unwrap().follower(0)[10];
    let offset = (follower_tip - tip).reject_from_normalized(tip_frame.tangent);
    let follower_turn = offset.angle_between(Vec3::Y);
    println!("the guide's tip turned {guide_turn:.4} rad, its follower {follower_turn:.4} rad about it");
    assert!(guide_turn > 0.5, "the guide twisted: {guide_turn} rad");
    assert!((follower_turn / guide_turn - 1.0).abs() < 0.01, "{follower_turn} against {guide_turn}");
    assert!(((follower_tip - tip).length() - 0.005).abs() < 1e-4, "the follower stays 5 mm from it");
}

#[test]
fn guide_and_follower_roots_are_the_groom_s_evenly_spread_roots() {
    let groom = HairGroom { strand_count: 100, followers_per_guide: 9, ..default() };
    let grown = groom.grow_with_followers().unwrap();
    assert_eq!(grown.len(), 100);
    let mut roots: Vec<Vec3> = grown
        .iter()
        .flat_map(|(guide, followers)| std::iter::once(guide.nodes[0]).chain(followers.curves.iter().map(|c| c[0])))
        .collect();
    let mut expected: Vec<Vec3> = groom.scalp.roots(1000).unwrap().iter().map(|root| root.position).collect();
    let key = |p: &Vec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
    roots.sort_by_key(key);
    expected.sort_by_key(key);
    assert_eq!(roots, expected, "guides and followers together have the roots of a 1 000-strand groom");
    // Each follower follows the guide whose root is nearest.
    let guide_roots: Vec<Vec3> = grown.iter().map(|(guide, _)| guide.nodes[0]).collect();
    for (guide, followers) in &grown {
        for curve in &followers.curves {
            let nearest = guide_roots.iter().map(|r| r.distance(curve[0])).fold(f32::INFINITY, f32::min);
            assert_eq!(guide.nodes[0].distance(curve[0]), nearest);
        }
    }
    let sizes: Vec<usize> = grown.iter().map(|(_, followers)| followers.curves.len()).collect();
    println!("followers per guide from {} to {}", sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
}

#[test]
fn followers_stay_out_of_a_head_turning_and_shaking() {
    let mut app = hair_app();
    let skull = Vec3::new(0.078, 0.095, 0.1);
    let groom = HairGroom { strand_count: 200, followers_per_guide: 10, segments: 16, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    let collider = app
        .world_mut()
        .spawn((HairCollider::ellipsoid(skull), HairColliderOf(head), Transform::from_xyz(0.0, 1.6, 0.0)))
        .id();
    app.update();
    let (mut total, mut deep, mut deepest) = (0usize, 0usize, 0.0_f32);
    for step in 1..=180 {
        // Turning at 2 rev/s and shaken sideways at up to 4 m/s (5 cm at 12.7 Hz).
        let t = step as f32 / 60.0;
        let pose = Transform::from_xyz(0.05 * (80.0 * t).sin(), 1.6, 0.0)
            .with_rotation(Quat::from_rotation_y(std::f32::consts::TAU * 2.0 * t));
        for entity in [head, collider] {
            *app.world_mut().get_mut::<Transform>(entity).unwrap() = pose;
        }
        app.update();
        for node in follower_nodes(&app, head) {
            let local = pose.rotation.inverse() * (node - pose.translation);
            let scaled = (local / skull).length();
            let depth = if scaled < 1.0 { local.length() * (1.0 / scaled - 1.0) } else { 0.0 };
            total += 1;
            deep += usize::from(depth > 1e-3);
            deepest = deepest.max(depth);
        }
    }
    println!("{deep} of {total} follower nodes more than 1 mm inside the skull; deepest {:.2} mm", 1e3 * deepest);
    assert!(deep * 100 < total, "{deep} of {total}");
    assert!(deepest < 5e-3, "{deepest} m");
}

#[test]
fn clumping_gathers_followers_onto_their_guide_towards_the_tip() {
    let mut app = hair_app();
    app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::ZERO;
    let head = app.world_mut().spawn((HairHead, Transform::default())).id();
    let mut strands = Vec::new();
    for clumping in [0.0, 0.5, 1.0] {
        let guide = HairStrand::straight(Vec3::ZERO, Vec3::X, 0.1, 10);
        let follower: Vec<Vec3> = guide.nodes.iter().map(|node| *node + Vec3::Y * 0.004).collect();
        let followers = HairFollowers { curves: vec![follower], clumping, ..default() };
        strands.push(app.world_mut().spawn((guide, followers, StrandOf(head))).id());
    }
    app.update();
    app.update();
    for (entity, clumping) in strands.into_iter().zip([0.0, 0.5, 1.0]) {
        let guide = &app.world().get::<StrandNodes>(entity).unwrap().positions;
        let follower = app.world().get::<FollowerNodes>(entity).unwrap().follower(0).to_vec();
        let (root_gap, tip_gap) = (follower[0].distance(guide[0]), follower[10].distance(guide[10]));
        println!("clumping {clumping}: root {:.2} mm, tip {:.2} mm from the guide", 1e3 * root_gap, 1e3 * tip_gap);
        assert!((root_gap - 0.004).abs() < 1e-6);
        assert!((tip_gap - 0.004 * (1.0 - clumping)).abs() < 1e-6, "{tip_gap} m");
    }
    let groom = HairGroom { follower_clumping: 1.5, followers_per_guide: 2, ..default() };
    assert!(groom.grow_with_followers().unwrap_err().to_string().contains("clumping"));
}

/// A weightless, straight 10 cm guide along X with `count` followers around it, 4 mm away in the plane
/// across it at evenly turning angles, spawned with `variation`; each follower's placed nodes after two
/// updates with the guide's nodes.
fn placed_around_one_guide(count: usize, variation: impl Fn(&mut HairFollowers)) -> (Vec<Vec<Vec3>>, Vec<Vec3>) {
    let mut app = hair_app();
    app.world_mut().resource_mut::<HairSettings>().gravity = Vec3::ZERO;
    let head = app.world_mut().spawn((HairHead, Transform::default())).id();
    let guide = HairStrand::straight(Vec3::ZERO, Vec3::X, 0.1, 10);
    let curves = (0..count)
        .map(|k| {
            let angle = std::f32::consts::TAU * k as f32 / count as f32;
            let across = 0.004 * Vec3::new(0.0, angle.cos(), angle.sin());
            guide.nodes.iter().map(|node| *node + across).collect()
        })
        .collect();
    let mut followers = HairFollowers { curves, ..default() };
    variation(&mut followers);
    let entity = app.world_mut().spawn((guide, followers, StrandOf(head))).id();
    app.update();
    app.update();
    let guide = app.world().get::<StrandNodes>(entity).unwrap().positions.clone();
    let placed = app.world().get::<FollowerNodes>(entity).unwrap();
    assert_eq!(placed.rejection(), None);
    ((0..count).map(|k| placed.follower(k).to_vec()).collect(), guide)
}

#[test]
fn each_follower_draws_its_own_clumping_and_scatter_from_its_root() {
    const COUNT: usize = 400;
    // Clumping 0.5 varied by 0.6: each follower's tip 4 mm × (1 − c) from the guide's, c uniform on
    // [0.2, 0.8], so the tips' gaps spread uniformly over [0.8, 3.2] mm with mean 2 mm.
    let (followers, guide) = placed_around_one_guide(COUNT, |followers| {
        (followers.clumping, followers.clumping_variation) = (0.5, 0.6);
    });
    let gaps: Vec<f32> = followers.iter().map(|follower| follower[10].distance(guide[10])).collect();
    let (least, most) = gaps.iter().fold((f32::MAX, 0.0_f32), |(a, b), &gap| (a.min(gap), b.max(gap)));
    let mean = gaps.iter().sum::<f32>() / COUNT as f32;
    println!(
        "clumping 0.5 ± 0.3: tips {:.3} to {:.3} mm from the guide's, mean {:.3} mm",
        1e3 * least,
        1e3 * most,
        1e3 * mean
    );
    for (follower, gap) in followers.iter().zip(&gaps) {
        assert!((follower[0].distance(guide[0]) - 0.004).abs() < 1e-6, "a root moved");
        // Linear in s: the midpoint's gap is halfway between the root's and the tip's.
        let middle = follower[5].distance(guide[5]);
        assert!((middle - 0.5 * (0.004 + gap)).abs() < 1e-6, "middle {middle}, tip {gap}");
    }
    assert!(least >= 0.0008 - 1e-6 && most <= 0.0032 + 1e-6, "{least} to {most} m");
    assert!(least < 0.0010 && most > 0.0030, "the gaps do not cover their range: {least} to {most} m");
    // The mean of 400 uniform draws on a 2.4 mm range: within 3 standard errors (0.10 mm).
    assert!((mean - 0.002).abs() < 1e-4, "mean {mean} m");
    let distinct = {
        let mut sorted: Vec<u32> = gaps.iter().map(|gap| (gap * 1e7) as u32).collect();
        sorted.sort_unstable();
        sorted.dedup();
        sorted.len()
    };
    assert!(distinct > COUNT * 9 / 10, "{distinct} distinct gaps of {COUNT}");

    // Scatter 3 mm: each follower moves across the guide by `a s²` (a uniform on [0, 3] mm) in a turning
    // direction; the root stays, the midpoint moves a quarter of the tip's amount.
    let scatter = 0.003;
    let (scattered, _) = placed_around_one_guide(COUNT, |followers| followers.scatter = scatter);
    let (plain, _) = placed_around_one_guide(COUNT, |_| {});
    let mut tip_moves = Vec::new();
    let mut direction_sum = Vec3::ZERO;
    for (moved, still) in scattered.iter().zip(&plain) {
        assert!(moved[0].distance(still[0]) < 1e-7, "a root moved");
        let (tip, middle) = (moved[10] - still[10], moved[5] - still[5]);
        assert!(tip.x.abs() < 1e-6 && middle.x.abs() < 1e-6, "moved along the guide: {tip}, {middle}");
        assert!((middle.length() - 0.25 * tip.length()).abs() < 2e-7, "middle {middle}, tip {tip}");
        assert!(tip.length() <= scatter + 1e-6, "{tip}");
        tip_moves.push(tip.length());
        direction_sum += tip.normalize_or_zero();
    }
    let mean = tip_moves.iter().sum::<f32>() / COUNT as f32;
    let largest = tip_moves.iter().fold(0.0_f32, |a, &b| a.max(b));
    let bias = direction_sum.length() / COUNT as f32;
    println!(
        "scatter 3 mm: tips moved {:.3} mm on average, at most {:.3} mm; mean direction {bias:.3}",
        1e3 * mean,
        1e3 * largest
    );
    // Uniform on [0, 3] mm: mean 1.5 mm within 3 standard errors (0.13 mm); directions spread all round.
    assert!((mean - 0.0015).abs() < 1.3e-4, "mean {mean} m");
    assert!(largest > 0.0028, "{largest} m");
    assert!(bias < 0.15, "the tips lean one way: {bias}");

    // The same roots draw the same variation, bound again.
    let (again, _) = placed_around_one_guide(COUNT, |followers| followers.scatter = scatter);
    assert_eq!(again, scattered);

    // Out of range: refused by name, and no follower placed.
    let mut app = hair_app();
    let head = app.world_mut().spawn((HairHead, Transform::default())).id();
    let bad = [(0.5, 1.5, 0.0, "clumping variation"), (0.5, 0.2, -0.001, "scatter"), (0.5, 0.2, f32::NAN, "scatter")];
    let entities: Vec<Entity> = bad
        .iter()
        .map(|&(clumping, clumping_variation, scatter, _)| {
            let guide = HairStrand::straight(Vec3::ZERO, Vec3::X, 0.1, 10);
            let curves = vec![guide.nodes.iter().map(|node| *node + Vec3::Y * 0.004).collect()];
            let followers = HairFollowers { curves, clumping, clumping_variation, scatter };
            app.world_mut().spawn((guide, followers, StrandOf(head))).id()
        })
        .collect();
    app.update();
    for (entity, (.., name)) in entities.into_iter().zip(bad) {
        let placed = app.world().get::<FollowerNodes>(entity).unwrap();
        let rejection = placed.rejection().unwrap_or_default();
        assert!(rejection.contains(name), "{rejection:?} does not name the {name}");
        assert!(!placed.is_placed());
    }
    for (groom, name) in [
        (HairGroom { follower_clumping_variation: -0.1, ..default() }, "variation"),
        (HairGroom { follower_scatter: f32::INFINITY, ..default() }, "scatter"),
    ] {
        let error = HairGroom { followers_per_guide: 2, strand_count: 10, ..groom }.grow_with_followers().unwrap_err();
        assert!(error.to_string().contains(name), "{error}");
    }
}

#[test]
fn followers_left_to_the_gpu_are_counted_but_placed_only_where_asked() {
    use bevy_hair_sim::followers::{FollowerPlacement, PlaceFollowersOnCpu};
    let (mut app, head, _) = weightless_head(40, 8);
    let guides = app.world().get::<HeadStrands>(head).unwrap().strands().to_vec();
    let placed =
        |app: &App| guides.iter().filter(|&&g| app.world().get::<FollowerNodes>(g).unwrap().is_placed()).count();
    assert_eq!(placed(&app), 40, "placed on the CPU without a placement resource");
    // The GPU places them: none placed here, and the positions placed before are dropped.
    app.insert_resource(FollowerPlacement::Gpu);
    app.update();
    assert_eq!(placed(&app), 0);
    assert!(guides.iter().all(|&g| app.world().get::<FollowerNodes>(g).unwrap().positions.is_empty()));
    assert_eq!(app.world().resource::<HairStatistics>().followers, 320, "bound followers are still counted");
    // One guide marked, then the whole head.
    app.world_mut().entity_mut(guides[7]).insert(PlaceFollowersOnCpu);
    app.update();
    assert_eq!(placed(&app), 1);
    assert!(app.world().get::<FollowerNodes>(guides[7]).unwrap().is_placed());
    assert_eq!(app.world().resource::<HairStatistics>().followers, 320);
    app.world_mut().entity_mut(head).insert(PlaceFollowersOnCpu);
    app.update();
    assert_eq!(placed(&app), 40);
    assert_eq!(app.world().resource::<HairStatistics>().followers, 320);
}
