//! Grooming: roots spread evenly over the scalp along its normals, strand counts and shapes as asked,
//! bad grooms rejected with their reason.

use hair_sim_support::example_scene as scene;

use bevy::math::{Affine3A, DVec3};
use bevy::prelude::*;
use bevy_hair_sim::groom::{GroomError, GroomObstacles, ScalpRoot};
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::rod::{ColliderShape, RigidPose};

/// A head-like skull: narrower than deep, centred above the head's origin.
fn skull() -> Scalp {
    Scalp { centre: Vec3::new(0.0, 0.02, 0.0), semi_axes: Vec3::new(0.075, 0.095, 0.1), ..default() }
}

/// Distance from each root to its nearest neighbour, m.
fn nearest_neighbour_distances(roots: &[ScalpRoot]) -> Vec<f32> {
    roots
        .iter()
        .enumerate()
        .map(|(index, root)| {
            roots
                .iter()
                .enumerate()
                .filter(|&(other, _)| other != index)
                .map(|(_, other)| root.position.distance(other.position))
                .fold(f32::INFINITY, f32::min)
        })
        .collect()
}

#[test]
fn roots_lie_on_the_skull_inside_the_hairline_with_the_exact_count() {
    let scalp = skull();
    for count in [1, 7, 100, 2000, 3117] {
        let roots = scalp.roots(count).unwrap();
        assert_eq!(roots.len(), count);
        for root in &roots {
            let on_unit_sphere = (root.position - scalp.centre) / scalp.semi_axes;
            assert!((on_unit_sphere.length() - 1.0).abs() < 1e-5, "root {root:?} is off the skull");
            let gradient = (on_unit_sphere / scalp.semi_axes).normalize();
            assert!(root.normal.cross(gradient).length() < 1e-5, "root {root:?} does not grow along the normal");
            assert!(root.normal.y >= scalp.nape_height, "root {root:?} below the nape");
            let facing_front = -root.normal.z / Vec2::new(root.normal.x, root.normal.z).length();
            assert!(facing_front < 0.7 || root.normal.y >= scalp.brow_height, "root {root:?} on the face");
        }
    }
}

#[test]
fn roots_are_spread_evenly_without_clumps_or_bald_patches() {
    let scalp = skull();
    let roots = scalp.roots(2000).unwrap();
    let distances = nearest_neighbour_distances(&roots);
    let mean = distances.iter().sum::<f32>() / distances.len() as f32;
    let (closest, farthest) =
        distances.iter().fold((f32::INFINITY, 0.0_f32), |(low, high), &d| (low.min(d), high.max(d)));
    println!("nearest neighbours: mean {:.2} mm, min {:.2}, max {:.2}", 1e3 * mean, 1e3 * closest, 1e3 * farthest);
    // Uniformly random roots would have a closest pair at a few percent of the mean spacing.
    assert!(closest > 0.6 * mean, "clump: two roots {closest} m apart against a mean spacing of {mean} m");
    assert!(farthest < 1.5 * mean, "a root stands {farthest} m from its neighbours against a mean spacing of {mean} m");

    // No bald patch: every point of the scalp (a spiral ten times denser) is near a root. Points on the
    // hairline have roots on one side only, hence more than a lattice's half spacing.
    let probes = scalp.roots(20_000).unwrap();
    let widest_gap = probes
        .iter()
        .map(|probe| roots.iter().map(|root| root.position.distance(probe.position)).fold(f32::INFINITY, f32::min))
        .fold(0.0_f32, f32::max);
    println!("widest gap: {:.2} mm", 1e3 * widest_gap);
    assert!(widest_gap < 1.25 * mean, "a bald patch: a scalp point {widest_gap} m from every root");
}

#[test]
fn grown_strands_have_the_style_lengths_and_root_along_the_normal() {
    for style in HairStyle::ALL {
        let groom =
            HairGroom { scalp: skull(), strand_count: 300, segments: 16, style, seed: 7, combing: None, ..default() };
        let strands = groom.grow().unwrap();
        let roots = groom.scalp.roots(300).unwrap();
        assert_eq!(strands.len(), 300);
        let (shortest, longest) = style.length_range();
        let lengths: Vec<f32> =
            strands.iter().map(|strand| strand.nodes.windows(2).map(|edge| edge[0].distance(edge[1])).sum()).collect();
        for ((strand, root), length) in strands.iter().zip(&roots).zip(&lengths) {
            assert_eq!(strand.nodes.len(), 17);
            assert_eq!(strand.nodes[0], root.position);
            assert!((strand.nodes[1] - strand.nodes[0]).angle_between(root.normal) < 1e-3, "{style:?} root edge");
            assert!((shortest - 1e-5..=longest + 1e-5).contains(length), "{style:?} strand of {length} m");
            assert!(strand.material_direction.dot(root.normal).abs() < 1e-5, "{style:?} material direction");
        }
        let spread =
            lengths.iter().fold(0.0_f32, |high, &l| high.max(l)) - lengths.iter().fold(1.0_f32, |low, &l| low.min(l));
        assert!(spread > 0.8 * (longest - shortest), "{style:?}: lengths vary by only {spread} m");
    }
}

#[test]
fn combed_strands_have_the_style_lengths_and_leave_the_root_along_the_scalp() {
    for style in HairStyle::ALL {
        let groom = HairGroom { scalp: skull(), strand_count: 300, segments: 16, style, seed: 7, ..default() };
        let combing = groom.combing.unwrap();
        let strands = groom.grow().unwrap();
        let roots = groom.scalp.roots(300).unwrap();
        let (shortest, longest) = style.length_range();
        for (strand, root) in strands.iter().zip(&roots) {
            let length: f32 = strand.nodes.windows(2).map(|edge| edge[0].distance(edge[1])).sum();
            assert_eq!(strand.nodes[0], root.position);
            let root_edge = strand.nodes[1] - strand.nodes[0];
            // Nearly along the scalp (within 30° of its tangent plane, or rising only by the lift on a
            // short edge), ending above it.
            let rise = root_edge.dot(root.normal);
            let lift = combing.lift + combing.layer_spread;
            assert!(rise < 0.5 * root_edge.length() || rise <= lift + 1e-5, "{style:?}: the root edge rises {rise} m");
            let above = (strand.nodes[1] - groom.scalp.centre) / groom.scalp.semi_axes;
            assert!(above.length() > 1.0, "{style:?}: node 1 is not above the scalp");
            // Chords of a path of the style's length: a little shorter where it bends, never longer.
            assert!((0.97 * shortest..=longest + 1e-5).contains(&length), "{style:?} strand of {length} m");
            assert!(strand.material_direction.dot(root_edge.normalize()).abs() < 1e-3, "{style:?} material direction");
            assert_eq!(strand.gravity_preload, 1.0);
        }
    }
}

/// The sharpest turn between consecutive edges of `nodes`, rad.
fn sharpest_turn(nodes: &[Vec3]) -> f32 {
    nodes.windows(3).map(|three| (three[1] - three[0]).angle_between(three[2] - three[1])).fold(0.0, f32::max)
}

/// The example's body under its head, head-local: neck, shoulders and torso.
fn example_body() -> Vec<(ColliderShape, RigidPose)> {
    let neck = DVec3::Y * f64::from(scene::NECK_HEIGHT);
    scene::BODY
        .iter()
        .map(|part| {
            let transform = part.transform();
            let pose = RigidPose::new(transform.rotation.as_dquat(), transform.translation.as_dvec3() - neck);
            (ColliderShape::capsule(f64::from(part.radius), f64::from(part.half_length)), pose)
        })
        .collect()
}

/// A groom of `style` on the example's skull: `strands` guides × 24 edges with `followers` each.
fn example_groom(style: HairStyle, strands: usize, followers: usize) -> HairGroom {
    HairGroom {
        scalp: scene::SCALP,
        strand_count: strands,
        segments: 24,
        style,
        seed: 1,
        followers_per_guide: followers,
        ..default()
    }
}

#[test]
fn combed_strands_and_their_followers_turn_smoothly_on_a_head_shaped_skull() {
    // Short hair combed all the way along the example's skull once ran into the underside of the skull,
    // where "down" along the scalp turns back on itself, and doubled back there (a turn of 180°, a strand
    // the rod refuses).
    for style in HairStyle::ALL {
        let groom = example_groom(style, 2000, 2);
        for obstacles in [GroomObstacles::default(), GroomObstacles::new(example_body())] {
            let grown = groom.grow_with_followers_around(None, &obstacles).unwrap();
            let hairs = grown.iter().flat_map(|(guide, followers)| {
                std::iter::once(guide.nodes.as_slice()).chain(followers.curves.iter().map(Vec::as_slice))
            });
            let sharpest = hairs.map(sharpest_turn).fold(0.0, f32::max);
            let around = if obstacles.is_empty() { "alone" } else { "over the body" };
            println!("{style:?}, {around}: sharpest turn {:.0}°", sharpest.to_degrees());
            // Curls of 6 mm radius on 1 cm edges turn by about 1.2 rad per edge; nothing folds.
            assert!(sharpest < 1.6, "{style:?}: a strand turns by {:.0}°", sharpest.to_degrees());
        }
    }
}

#[test]
fn combed_hair_covers_its_scalp_down_to_the_hairline_and_across_the_parting() {
    // The example's groom as grown, with its followers: 22 000 hairs drawn as wide as the renderer draws
    // them (each the width of the 100 000 / 22 000 fibres it stands for).
    use bevy_hair_sim::debug::coverage;
    let groom = example_groom(HairStyle::Straight, 2000, 10);
    let width = 2.0 * 40e-6 * groom.hair_count as f32 / 22_000.0;
    let bare = |combing: Combing| {
        let grown = HairGroom { combing: Some(combing), ..groom.clone() }
            .grow_with_followers_around(None, &GroomObstacles::new(example_body()))
            .unwrap();
        let hairs = grown.iter().flat_map(|(guide, followers)| {
            std::iter::once(guide.nodes.as_slice()).chain(followers.curves.iter().map(Vec::as_slice))
        });
        coverage::bare_scalp(&groom.scalp, &Affine3A::IDENTITY, hairs, 2000, (0.003, width)).unwrap()
    };
    let scalp = groom.scalp;
    let at_the_parting =
        |root: &ScalpRoot| (root.position.x - scalp.centre.x - 0.02).abs() < 0.01 && root.normal.y > 0.3;
    let below_the_widest = |root: &ScalpRoot| root.normal.y < 0.0;
    let roots = scalp.roots(2000).unwrap();
    let share = |bare: &coverage::BareScalp, part: &dyn Fn(&ScalpRoot) -> bool| {
        let all = roots.iter().filter(|root| part(root)).count();
        bare.points.iter().filter(|root| part(root)).count() as f32 / all as f32
    };
    let combed = bare(Combing::default());
    // Combed only sideways at the crown, turning fully sideways within 1.5 cm of the parting.
    let parted = bare(Combing { crown_sweep: 0.0, parting_blend: 0.015, ..default() });
    // Without the sweep back along the parting's front, the hair there runs sideways off the line.
    let unswept = bare(Combing { parting_sweep: 0.0, ..default() });
    let everywhere = combed.points.len() as f32 / combed.judged as f32;
    // Bare points further inside the hairline than its fade (where the hair thins out on purpose).
    let past_the_fade = |bare: &coverage::BareScalp| {
        let depths = bare.points.iter().map(|root| scalp.depth_inside_hairline(root.position));
        depths.filter(|&depth| depth > groom.hairline_fade).count()
    };
    println!(
        "bare: {:.1} % of the scalp, {:.1} % below its widest part, {:.1} % at the parting (combed only \
         sideways at the crown: {:.1} %)",
        100.0 * everywhere,
        100.0 * share(&combed, &below_the_widest),
        100.0 * share(&combed, &at_the_parting),
        100.0 * share(&parted, &at_the_parting),
    );
    println!(
        "bare points further inside the hairline than its fade: {} (the parting's front not swept back: {})",
        past_the_fade(&combed),
        past_the_fade(&unswept)
    );
    // The hair lies on the skull down to its hairline, not only to its widest part.
    assert!(share(&combed, &below_the_widest) < 0.03, "below the widest part");
    // The parting is a line the hair turns at, not a stripe it leaves bare; combed only sideways it is.
    assert!(share(&combed, &at_the_parting) < 0.15, "at the parting");
    assert!(share(&parted, &at_the_parting) > 0.3, "a parting the hair leaves at once");
    assert!(everywhere < 0.02, "{everywhere} of the scalp bare");
    // The parting's front: hair runs back over the line, so the scalp is bare only at the hairline's
    // edge, where the combed hair leaves the hairline.
    assert_eq!(past_the_fade(&combed), 0, "bare beyond the hairline's fade");
    assert!(past_the_fade(&unswept) >= 3, "the parting's front not swept back");
}

#[test]
fn falling_hair_drapes_over_the_body_instead_of_passing_through_it() {
    let body = example_body();
    let obstacles = GroomObstacles::new(body.clone());
    for style in [HairStyle::Straight, HairStyle::Long, HairStyle::Curly] {
        let groom = HairGroom { scalp: scene::SCALP, strand_count: 600, segments: 24, style, seed: 3, ..default() };
        let (shortest, longest) = style.length_range();
        let depth = |strands: &[HairStrand]| {
            let nodes = strands.iter().flat_map(|strand| &strand.nodes);
            nodes
                .map(|node| {
                    let inside = body.iter().map(|(shape, pose)| -shape.distance_bound(pose.to_local(node.as_dvec3())));
                    inside.fold(0.0_f64, f64::max)
                })
                .fold(0.0, f64::max)
        };
        let through = groom.grow().unwrap();
        let draped: Vec<HairStrand> =
            groom.grow_with_followers_around(None, &obstacles).unwrap().into_iter().map(|(strand, _)| strand).collect();
        let (before, after) = (depth(&through), depth(&draped));
        println!("{style:?}: deepest node in the body {:.1} mm, draped {:.2} mm", 1e3 * before, 1e3 * after);
        // Every node outside the body: it lies a lift above it, to the ellipsoid-free capsules' exactness.
        assert_eq!(after, 0.0, "{style:?}: a draped node is {after} m inside the body");
        for strand in &draped {
            let length: f32 = strand.nodes.windows(2).map(|edge| edge[0].distance(edge[1])).sum();
            assert!((0.97 * shortest..=longest + 1e-5).contains(&length), "{style:?} strand of {length} m");
        }
        if style == HairStyle::Long {
            assert!(before > 0.05, "the long hair reaches the shoulders and back: {before} m deep without draping");
        }
    }
}

#[test]
fn followers_keep_to_their_guide_all_along_its_length() {
    // Grown each on its own, a follower left its guide by centimetres (another length, the other side of
    // a shoulder): 2 to 4 cm at the median, up to 21 cm; its offset, carried in the guide's turning
    // frame, then swung it far from the hair. Each follower now lies as far from its guide everywhere as
    // at the root.
    let obstacles = GroomObstacles::new(example_body());
    for style in HairStyle::ALL {
        let groom = example_groom(style, 500, 10);
        let (mut farthest, mut widest) = (0.0_f32, 0.0_f32);
        for (guide, followers) in groom.grow_with_followers_around(None, &obstacles).unwrap() {
            for curve in &followers.curves {
                let at_root = curve[0].distance(guide.nodes[0]);
                let along = curve.iter().zip(&guide.nodes).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max);
                (farthest, widest) = (farthest.max(along - at_root), widest.max(at_root));
            }
        }
        println!(
            "{style:?}: followers up to {:.1} mm from their guide's root, {farthest:e} m farther along",
            1e3 * widest
        );
        assert!(farthest < 1e-5, "{style:?}: a follower leaves its guide by {farthest} m beyond its root's offset");
    }
}

#[test]
fn the_same_seed_grows_the_same_hair_and_another_seed_other_hair() {
    let groom = HairGroom { strand_count: 50, style: HairStyle::Curly, ..default() };
    assert_eq!(groom.grow().unwrap(), groom.grow().unwrap());
    assert_ne!(groom.grow().unwrap(), HairGroom { seed: 1, ..groom.clone() }.grow().unwrap());
}

#[test]
fn invalid_grooms_are_rejected_with_their_reason() {
    let cases = [
        (HairGroom { segments: 1, ..default() }, "at least 2 segments"),
        (HairGroom { scalp: Scalp { semi_axes: Vec3::new(0.1, 0.0, 0.1), ..default() }, ..default() }, "semi-axes"),
        (HairGroom { scalp: Scalp { centre: Vec3::NAN, ..default() }, ..default() }, "finite centre"),
        (HairGroom { scalp: Scalp { nape_height: f32::NAN, ..default() }, ..default() }, "nape height"),
        (HairGroom { scalp: Scalp { brow_height: 1.5, ..default() }, ..default() }, "brow height"),
        (HairGroom { scalp: Scalp { nape_height: 1.0, brow_height: 1.0, ..default() }, ..default() }, "no room"),
        (HairGroom { gravity_preload: 1.5, ..default() }, "gravity preload"),
        (HairGroom { combing: Some(Combing { lift: -0.001, ..default() }), ..default() }, "combing"),
        (HairGroom { combing: Some(Combing { crown_sweep: -0.5, ..default() }), ..default() }, "crown_sweep"),
        (HairGroom { combing: Some(Combing { parting_blend: 0.0, ..default() }), ..default() }, "parting_blend"),
        (HairGroom { combing: Some(Combing { parting_sweep: -1.0, ..default() }), ..default() }, "parting_sweep"),
    ];
    for (groom, reason) in cases {
        let error: GroomError = groom.grow().unwrap_err();
        assert!(error.to_string().contains(reason), "{error} should say {reason:?}");
    }
    assert!(HairGroom { strand_count: 0, ..default() }.grow().unwrap().is_empty());
    for fade in [-0.001, f32::NAN, f32::INFINITY] {
        let error = HairGroom { hairline_fade: fade, ..default() }.grow().unwrap_err();
        assert!(matches!(error, GroomError::HairlineFade(_)) && error.to_string().contains("hairline fade"), "{error}");
    }
}

#[test]
fn depth_inside_the_hairline_is_the_distance_along_the_skull_near_it() {
    // A sphere of 10 cm whose hairline is one circle of latitude (normal up component −0.35): the depth
    // of a point is its arc from that circle along the meridian, R (latitude − latitude of the hairline).
    let scalp =
        Scalp { centre: Vec3::new(0.0, 0.1, 0.0), semi_axes: Vec3::splat(0.1), nape_height: -0.35, brow_height: -0.35 };
    let hairline = (-0.35_f32).asin();
    for longitude in [0.0_f32, 1.0, 2.5, 4.0] {
        for arc in [-0.004_f32, -0.001, 0.0005, 0.002, 0.005, 0.008, 0.012] {
            let latitude = hairline + arc / 0.1;
            let direction =
                Vec3::new(latitude.cos() * longitude.cos(), latitude.sin(), latitude.cos() * longitude.sin());
            // Off the surface too: the point radially under it is judged.
            let depth = scalp.depth_inside_hairline(scalp.centre + 0.13 * direction);
            assert!(
                (depth - arc).abs() < 0.02 * arc.abs() + 1e-5,
                "arc {arc} m at longitude {longitude}: depth {depth}"
            );
        }
    }
}

#[test]
fn the_drawn_hair_thins_out_towards_the_hairline_over_its_fade() {
    use bevy_hair_sim::groom::{HAIRLINE_SPARSEST, HAIRLINE_THINNEST};
    let groom = example_groom(HairStyle::Straight, 2000, 10);
    let grown = groom.grow_with_followers().unwrap();
    let widths = groom.hairline_widths(&grown);
    assert_eq!(widths, groom.hairline_widths(&grown), "the same groom thins the same hairs");
    assert_eq!(widths.len(), grown.len());
    // Per band of depth inside the hairline (2 mm each, then the rest): hairs drawn, and their mean share.
    let mut bands = [(0_usize, 0_usize, 0.0_f32); 5];
    for ((strand, followers), widths) in grown.iter().zip(&widths) {
        let roots = std::iter::once(strand.nodes[0]).chain(followers.curves.iter().map(|curve| curve[0]));
        assert_eq!(widths.hairs.len(), 1 + followers.curves.len());
        for (root, &share) in roots.zip(&widths.hairs) {
            let depth = groom.scalp.depth_inside_hairline(root);
            let band = ((depth / 0.002).max(0.0) as usize).min(4);
            if depth >= groom.hairline_fade {
                assert_eq!(share, 1.0, "a hair {depth} m inside the hairline is drawn whole");
            } else {
                assert!(share == 0.0 || (HAIRLINE_THINNEST..=1.0).contains(&share), "{share} at {depth} m");
            }
            bands[band].0 += 1;
            if share > 0.0 {
                bands[band].1 += 1;
                bands[band].2 += share;
            }
        }
    }
    let drawn: Vec<f32> = bands.iter().map(|&(all, drawn, _)| drawn as f32 / all as f32).collect();
    let mean: Vec<f32> = bands.iter().map(|&(_, drawn, sum)| sum / drawn as f32).collect();
    println!(
        "hairs per 2 mm band from the hairline: {:?}, drawn {drawn:?}, mean share {mean:?}",
        bands.map(|band| band.0)
    );
    // Sparse and thin at the hairline, rising band by band to whole.
    assert!(bands[0].0 > 200, "enough hairs in the first band to judge it: {}", bands[0].0);
    assert!((drawn[0] - HAIRLINE_SPARSEST).abs() < 0.12 && mean[0] < HAIRLINE_THINNEST + 0.1, "{drawn:?} {mean:?}");
    assert!(drawn.windows(2).all(|pair| pair[0] < pair[1]) && mean.windows(2).all(|pair| pair[0] < pair[1]));
    assert_eq!((drawn[4], mean[4]), (1.0, 1.0));
    // No fade: every hair whole.
    let hard = HairGroom { hairline_fade: 0.0, ..groom.clone() };
    assert!(hard.hairline_widths(&grown).iter().all(|widths| widths.hairs.iter().all(|&share| share == 1.0)));
}
