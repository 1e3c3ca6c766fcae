//! What the hair renderer computes on the CPU, checked without a GPU: the layout of a head's hairs in the
//! node buffer, the template mesh (vertices, triangles, widths), the interpolated positions, and the
//! colours from melanin.

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::render::{GuideLayout, HairStrips, ribbon_width};
use hair_sim_support::headless::hair_app;

/// A head with a curly groom of 30 guides × 10 edges, 3 followers each, moving: stepped twice, then
/// moved so that the last two steps differ.
fn moving_head() -> (App, Entity) {
    let mut app = hair_app();
    let groom =
        HairGroom { strand_count: 30, followers_per_guide: 3, segments: 10, style: HairStyle::Curly, ..default() };
    let head = app.world_mut().spawn((HairHead, groom, Transform::from_xyz(0.0, 1.6, 0.0))).id();
    for frame in 0..6 {
        app.world_mut().get_mut::<Transform>(head).unwrap().translation.x = 0.02 * frame as f32;
        app.update();
    }
    (app, head)
}

/// The layout of `head`'s guides as the renderer reads it (radius 40 µm).
fn layout(app: &App, head: Entity) -> Vec<GuideLayout> {
    let world = app.world();
    world
        .get::<HeadStrands>(head)
        .unwrap()
        .strands()
        .iter()
        .map(|&entity| {
            GuideLayout::new(
                entity,
                world.get::<StrandNodes>(entity).unwrap(),
                world.get::<FollowerNodes>(entity),
                4e-5,
            )
        })
        .collect()
}

#[test]
fn hairs_are_laid_out_guide_then_followers_and_relaid_only_on_change() {
    let (app, head) = moving_head();
    let guides = layout(&app, head);
    let mut strips = HairStrips::default();
    assert!(strips.set_layout(guides.iter().copied()), "the first layout is new");
    assert!(!strips.set_layout(guides.iter().copied()), "the same guides keep the layout");

    // 30 guides with 90 followers between them (each follows its nearest guide), hairs of 11 nodes, back
    // to back, each guide before its followers.
    let hairs: u32 = guides.iter().map(|guide| 1 + guide.followers).sum();
    assert_eq!(hairs, 30 + 90);
    assert_eq!(strips.hairs().len(), 120);
    assert_eq!(strips.node_count(), 120 * 11);
    let mut next = 0;
    for hair in strips.hairs() {
        assert_eq!((hair.first_node, hair.nodes), (next, 11));
        next += hair.nodes;
    }

    // A guide that loses a follower, or a guide removed, changes the layout.
    let mut changed = guides.clone();
    changed[7].followers += 1;
    assert!(strips.set_layout(changed.iter().copied()));
    assert_eq!(strips.node_count(), 121 * 11);
    assert!(strips.set_layout(guides[..29].iter().copied()));
    assert_eq!(strips.hairs().len() as u32, 120 - 1 - guides[29].followers);
    assert!(strips.set_layout(guides.iter().copied()));
    assert_eq!(strips.node_count(), 120 * 11);
}

#[test]
fn drawn_hairs_end_short_of_their_tips_by_up_to_the_length_variation() {
    let (app, head) = moving_head();
    let mut strips = HairStrips::default();
    strips.set_layout(layout(&app, head));
    let (taper, variation) = (0.5, 0.3);
    let vertices = strips.vertices((1.0, taper, variation), |_| None);
    let mut shortened = Vec::new();
    for hair in strips.hairs() {
        let edges = hair.nodes - 1;
        let vertex = |along: u32, side: u32| vertices[(2 * (hair.first_node + along) + side) as usize];
        let last = vertex(0, 0)[2] >> 16;
        assert!(last >= 1 && (edges - last) as f32 <= variation * edges as f32 + 0.5, "{last} of {edges} edges");
        for along in 0..hair.nodes {
            for side in 0..2 {
                let vertex = vertex(along, side);
                let radius = f32::from_bits(vertex[3]);
                assert_eq!(vertex[2] >> 16, last, "one last node for the whole hair");
                if along <= last {
                    // Drawn to its own end, tapered to it.
                    assert_eq!((vertex[0], vertex[2] >> 1 & 0x7fff), (hair.first_node + along, along));
                    let expected = 4e-5 * (1.0 - taper * along as f32 / last as f32);
                    assert!((radius - expected).abs() < 1e-6 * expected, "radius {radius} at {along}");
                } else {
                    // Beyond it, its last node again, with no width: no area drawn.
                    assert_eq!((vertex[0], vertex[2] >> 1 & 0x7fff, radius), (hair.first_node + last, last, 0.0));
                }
            }
        }
        shortened.push(edges - last);
    }
    // Lengths spread over the whole range, not one for every hair; the same each time the mesh is made.
    let longest_cut = *shortened.iter().max().unwrap();
    let kinds = shortened.iter().collect::<std::collections::BTreeSet<_>>().len();
    println!("edges taken off: {kinds} different counts, up to {longest_cut}");
    assert!(kinds >= 3 && shortened.contains(&0) && longest_cut >= 2, "{shortened:?}");
    assert_eq!(strips.vertices((1.0, taper, variation), |_| None), vertices);
    assert_eq!(strips.vertices((1.0, taper, 0.0), |_| None), strips.vertices((1.0, taper, 0.0), |_| None));
}

#[test]
fn the_template_mesh_has_two_tapered_sides_per_node_and_two_triangles_per_segment() {
    let (app, head) = moving_head();
    let mut strips = HairStrips::default();
    strips.set_layout(layout(&app, head));
    let (scale, taper) = (1.5, 0.4);
    let vertices = strips.vertices((scale, taper, 0.0), |_| None);
    assert_eq!(vertices.len(), 2 * strips.node_count());
    for (index, hair) in strips.hairs().iter().enumerate() {
        for along in 0..hair.nodes {
            for side in 0..2 {
                let vertex = vertices[(2 * (hair.first_node + along) + side) as usize];
                assert_eq!(vertex[0], hair.first_node + along, "node");
                assert_eq!(vertex[1], index as u32, "hair");
                assert_eq!(vertex[2] & 1, side, "side");
                assert_eq!(vertex[2] >> 1 & 0x7fff, along, "index along the hair");
                assert_eq!(vertex[2] >> 16, hair.nodes - 1, "last index");
                // Radius tapered linearly from 1.5 × 40 µm at the root to 60 % of that at the tip.
                let expected = 4e-5 * scale * (1.0 - taper * along as f32 / (hair.nodes - 1) as f32);
                let radius = f32::from_bits(vertex[3]);
                assert!((radius - expected).abs() < 1e-6 * expected, "radius {radius} at {along}, expected {expected}");
            }
        }
    }

    let indices = strips.indices();
    let segments: u32 = strips.hairs().iter().map(|hair| hair.nodes - 1).sum();
    assert_eq!(indices.len() as u32, 6 * segments);
    for triangle in indices.chunks_exact(3) {
        let nodes: Vec<u32> = triangle.iter().map(|&v| vertices[v as usize][0]).collect();
        let hairs: Vec<u32> = triangle.iter().map(|&v| vertices[v as usize][1]).collect();
        assert!(hairs.iter().all(|&h| h == hairs[0]), "a triangle within one hair: {triangle:?}");
        let span = nodes.iter().max().unwrap() - nodes.iter().min().unwrap();
        assert_eq!(span, 1, "a triangle spans one segment: {triangle:?}");
        let sides: u32 = triangle.iter().map(|&v| vertices[v as usize][2] & 1).sum();
        assert!(sides == 1 || sides == 2, "a triangle has both sides: {triangle:?}");
        assert!(triangle[0] != triangle[1] && triangle[1] != triangle[2] && triangle[0] != triangle[2]);
    }
}

#[test]
fn hairs_given_their_own_colours_carry_them_node_by_node_and_the_others_none() {
    let (app, head) = moving_head();
    let guides = layout(&app, head);
    let mut strips = HairStrips::default();
    strips.set_layout(guides.iter().copied());
    // Guide 0: every hair coloured, red at the root blending to blue at the tip. Guide 1: its follower 1
    // given one colour too few (drawn in the appearance's colours). The rest: none.
    let blend = |nodes: u32| {
        (0..nodes)
            .map(|node| LinearRgba::rgb(1.0 - node as f32 / (nodes - 1) as f32, 0.0, node as f32 / (nodes - 1) as f32))
            .collect::<Vec<_>>()
    };
    let first = StrandColors { hairs: vec![blend(guides[0].nodes); 1 + guides[0].followers as usize] };
    let mut second = StrandColors { hairs: vec![blend(guides[1].nodes); 1 + guides[1].followers as usize] };
    second.hairs[1].pop();
    let colors = strips.colors(|entity| {
        if entity == guides[0].entity {
            Some(&first)
        } else if entity == guides[1].entity {
            Some(&second)
        } else {
            None
        }
    });
    assert_eq!(colors.len(), 2 * strips.node_count());
    let srgb = |color: LinearRgba| {
        let [r, g, b, _] = Srgba::from(color).to_u8_array();
        u32::from_le_bytes([r, g, b, 255])
    };
    let mut hair = 0;
    for (index, guide) in guides.iter().enumerate() {
        for follower in 0..=guide.followers {
            let drawn = strips.hairs()[hair];
            for along in 0..drawn.nodes {
                let expected = match (index, follower) {
                    (0, _) => srgb(blend(drawn.nodes)[along as usize]),
                    (1, 1) => 0,
                    (1, _) => srgb(blend(drawn.nodes)[along as usize]),
                    _ => 0,
                };
                for side in 0..2 {
                    assert_eq!(
                        colors[(2 * (drawn.first_node + along) + side) as usize],
                        expected,
                        "hair {hair} node {along}"
                    );
                }
            }
            hair += 1;
        }
    }
    // Pure red at a root, pure blue at a tip, as sRGB bytes.
    assert_eq!(colors[0], 0xff00_00ff);
    assert_eq!(colors[2 * (guides[0].nodes as usize - 1)], 0xffff_0000);
}

#[test]
fn positions_are_interpolated_between_the_last_two_steps_in_parallel() {
    let (app, head) = moving_head();
    let world = app.world();
    let guides = layout(&app, head);
    let lookup = |entity| Some((world.get::<StrandNodes>(entity)?, world.get::<FollowerNodes>(entity)));
    let mut strips = HairStrips::default();
    strips.set_layout(guides.iter().copied());
    let alpha = 0.3;
    let (low, high) = strips.fill(alpha, 1, lookup).expect("hair to draw");

    // Every node against the components, interpolated by hand.
    let mut expected = Vec::new();
    for guide in &guides {
        let nodes = world.get::<StrandNodes>(guide.entity).unwrap();
        let followers = world.get::<FollowerNodes>(guide.entity).unwrap();
        assert_ne!(nodes.previous_positions, nodes.positions, "the head moved");
        expected.extend(nodes.previous_positions.iter().zip(&nodes.positions).map(|(a, b)| a.lerp(*b, alpha)));
        expected.extend(followers.previous_positions.iter().zip(&followers.positions).map(|(a, b)| a.lerp(*b, alpha)));
    }
    assert_eq!(expected.len(), strips.node_count());
    let worst = expected
        .iter()
        .zip(strips.positions().chunks_exact(3))
        .map(|(e, p)| e.distance(Vec3::new(p[0], p[1], p[2])))
        .fold(0.0, f32::max);
    assert!(worst < 1e-6, "{worst} m");
    let (expected_low, expected_high) =
        expected.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
    assert_eq!((low, high), (expected_low, expected_high));

    // Two threads (several pieces) write the same bytes.
    let single = strips.positions().to_vec();
    let mut parallel = HairStrips::default();
    parallel.set_layout(guides.iter().copied());
    assert_eq!(parallel.fill(alpha, 2, lookup), Some((low, high)));
    assert_eq!(parallel.positions(), &single[..]);

    // At alpha 1 the buffer is the last step.
    strips.fill(1.0, 2, lookup);
    let last = world.get::<StrandNodes>(guides[0].entity).unwrap().positions[4];
    assert_eq!(&strips.positions()[12..15], &[last.x, last.y, last.z]);
}

#[test]
fn sub_pixel_hairs_are_widened_with_their_coverage_lowered_in_proportion() {
    // An 80 µm hair where a pixel spans 0.5 mm: drawn one pixel wide, 16 % covered.
    let (width, coverage) = ribbon_width(8e-5, 5e-4, 1.0);
    assert_eq!(width, 5e-4);
    assert!((coverage - 0.16).abs() < 1e-6, "{coverage}");
    // The drawn area is the true one at any distance.
    for pixel in [1e-6, 1e-5, 8e-5, 1e-4, 1e-3, 1e-2] {
        let (width, coverage) = ribbon_width(8e-5, pixel, 1.5);
        assert!((width * coverage - 8e-5).abs() < 1e-12, "pixel {pixel}: {width} × {coverage}");
        assert!(coverage <= 1.0 && width >= 1.5 * pixel);
    }
    // A hair wider than the minimum is drawn as it is, fully covered.
    assert_eq!(ribbon_width(8e-5, 1e-5, 1.0), (8e-5, 1.0));
    assert_eq!(ribbon_width(0.0, 0.0, 1.0), (0.0, 0.0));
}

#[test]
fn melanin_darkens_and_reddens_hair_as_in_real_hair() {
    let luminance = |color: Color| {
        let linear = color.to_linear();
        0.2126 * linear.red + 0.7152 * linear.green + 0.0722 * linear.blue
    };
    let redness = |color: Color| {
        let linear = color.to_linear();
        linear.red / linear.green
    };
    // More eumelanin, darker hair, strictly.
    let mut last = f32::INFINITY;
    for eumelanin in [0.0, 0.1, 0.3, 1.0, 3.0, 8.0] {
        let y = luminance(HairAppearance::from_melanin(eumelanin, 0.0).root_color);
        assert!(y < last, "eumelanin {eumelanin}: luminance {y} not below {last}");
        last = y;
    }
    // No pigment is white; black hair reflects under 0.1 % (linear).
    assert!((luminance(HairAppearance::from_melanin(0.0, 0.0).root_color) - 1.0).abs() < 1e-6);
    assert!(luminance(HairAppearance::from_melanin(8.0, 0.0).root_color) < 1e-3);
    // Pheomelanin makes hair redder; eumelanin alone already makes it warm (brown, not grey).
    let brown = HairAppearance::from_melanin(1.0, 0.0).root_color;
    let auburn = HairAppearance::from_melanin(1.0, 1.0).root_color;
    assert!(redness(brown) > 1.5, "{}", redness(brown));
    assert!(redness(auburn) > redness(brown));
    // Tips lighter than roots.
    let appearance = HairAppearance::default();
    assert!(luminance(appearance.tip_color) > luminance(appearance.root_color));
    // Every preset is valid; an invalid field is named.
    for (name, preset) in HairAppearance::presets() {
        assert!(preset.validate().is_ok(), "{name}");
    }
    let invalid = HairAppearance { tip_taper: 1.5, ..default() };
    assert!(invalid.validate().unwrap_err().contains("tip_taper"));
    let invalid = HairAppearance { length_variation: f32::NAN, ..default() };
    assert!(invalid.validate().unwrap_err().contains("length_variation"));
}

#[test]
fn hairs_are_drawn_with_their_share_of_the_strand_width() {
    let (app, head) = moving_head();
    let world = app.world();
    let mut strips = HairStrips::default();
    strips.set_layout(layout(&app, head));
    let guides = strips.guides().to_vec();
    // The groom gave the strands near its hairline their widths, as it grows them.
    let groom = world.get::<HairGroom>(head).unwrap();
    let expected = groom.hairline_widths(&groom.grow_with_followers().unwrap());
    let given: Vec<Option<&StrandWidths>> =
        guides.iter().map(|guide| world.get::<StrandWidths>(guide.entity)).collect();
    for (given, expected) in given.iter().zip(&expected) {
        let thinned = expected.hairs.iter().any(|&share| share < 1.0);
        assert_eq!(*given, thinned.then_some(expected), "only strands with a thinned hair carry widths");
    }
    assert!(given.iter().any(Option::is_some), "30 guides over the scalp: some root near the hairline");
    // A strand's own widths: halved, left out, not finite (whole), past 1 (whole), past its list (whole).
    let own = StrandWidths { hairs: vec![0.5, 0.0, f32::NAN, 2.0] };
    let widths =
        |entity: Entity| if entity == guides[0].entity { Some(&own) } else { world.get::<StrandWidths>(entity) };
    let vertices = strips.vertices((1.0, 0.0, 0.0), widths);
    let root_radius = |hair: usize| f32::from_bits(vertices[2 * strips.hairs()[hair].first_node as usize][3]);
    let mut hair = 0;
    for (guide, given) in guides.iter().zip(&given) {
        for index in 0..=guide.followers as usize {
            let share = if guide.entity == guides[0].entity {
                [0.5, 0.0, 1.0, 1.0].get(index).copied().unwrap_or(1.0)
            } else {
                given.map_or(1.0, |given| given.hairs[index])
            };
            assert_eq!(root_radius(hair), 4e-5 * share, "hair {index} of guide {}", guide.entity);
            // Along the whole hair (no taper asked), the same.
            let drawn = strips.hairs()[hair];
            for along in 0..drawn.nodes {
                let vertex = vertices[(2 * (drawn.first_node + along)) as usize];
                assert_eq!(f32::from_bits(vertex[3]), 4e-5 * share);
            }
            hair += 1;
        }
    }
}
