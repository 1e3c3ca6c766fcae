//! Grooms grown on a scalp mesh and groom files fitted to one: roots spread over the mesh by area times
//! the density painted in its vertex colours, evenly (no two roots much nearer than hexagonal packing
//! allows), inside the hairline; combed hair lies along the mesh without entering it; a head with a scalp
//! mesh grows its groom on the mesh once the mesh has loaded; a groom file in other units, moved off its
//! head, is fitted back onto the scalp.

use bevy::asset::AssetPlugin;
use bevy::math::Affine3A;
use bevy::prelude::*;
use bevy::transform::TransformPlugin;
use bevy_hair_sim::groom::ScalpSurface;
use bevy_hair_sim::prelude::*;
use bevy_hair_sim::scalp::ScalpRootBinding;
use hair_sim_support::headless::{hair_app_with, strand};
use hair_sim_support::sphere_cap;

/// The scalp's radius, m.
const RADIUS: f32 = 0.1;

/// A cap over the top 100° of a sphere of [`RADIUS`] about the origin (`rings` × `2 rings` quads), its
/// vertices coloured by `color(position)`.
fn scalp_cap(rings: u32, color: impl Fn(Vec3) -> [f32; 4]) -> Mesh {
    let mesh = sphere_cap(Vec3::ZERO, RADIUS, rings, 2 * rings);
    let positions = mesh.attribute(Mesh::ATTRIBUTE_POSITION).unwrap().as_float3().unwrap();
    let colors: Vec<[f32; 4]> = positions.iter().map(|&position| color(Vec3::from(position))).collect();
    mesh.with_inserted_attribute(Mesh::ATTRIBUTE_COLOR, colors)
}

/// A groom of `strand_count` straight strands with `followers` each, no hairline to speak of.
fn groom(strand_count: usize, followers: usize) -> HairGroom {
    HairGroom {
        strand_count,
        followers_per_guide: followers,
        scalp: Scalp { nape_height: -1.0, brow_height: -1.0, ..default() },
        ..default()
    }
}

/// The nearest distance from each of `points` to another, m.
fn nearest_neighbours(points: &[Vec3]) -> Vec<f32> {
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            points.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, q)| p.distance(*q)).fold(f32::MAX, f32::min)
        })
        .collect()
}

#[test]
fn roots_grown_on_a_scalp_mesh_are_spread_by_area_and_painted_density_evenly() {
    // Full density on the left (−x), a quarter on the right, painted in the vertex colours.
    let mesh = scalp_cap(24, |p| if p.x < 0.0 { [1.0; 4] } else { [0.25, 0.25, 0.25, 1.0] });
    let surface = ScalpSurface::from_mesh(&mesh, Affine3A::IDENTITY).expect("the cap is a surface");
    let (area, hair_area) = surface.area();
    // The cap's area, 2πR²(1 − cos 100°), less the facets' shortfall.
    let cap = 2.0 * std::f32::consts::PI * RADIUS * RADIUS * (1.0 - 100f32.to_radians().cos());
    assert!((area / cap - 1.0).abs() < 0.01, "area {area} against the cap's {cap}");
    let (guides, followers) = (400, 4);
    let grown = groom(guides, followers).grow_with_followers_on(Some(&surface)).expect("the groom grows");
    assert_eq!(grown.len(), guides);
    let roots: Vec<Vec3> = grown
        .iter()
        .flat_map(|(guide, following)| std::iter::once(guide.nodes[0]).chain(following.curves.iter().map(|c| c[0])))
        .collect();
    assert_eq!(roots.len(), guides * (1 + followers));
    // On the mesh.
    let off = roots.iter().map(|&root| surface.nearest(root).0.distance(root)).fold(0.0, f32::max);
    assert!(off < 1e-6, "a root {off} m off the mesh");
    // By area times density: away from the blend across x = 0, four times as many on the left.
    let (left, right) = (roots.iter().filter(|p| p.x < -0.01).count(), roots.iter().filter(|p| p.x > 0.01).count());
    let ratio = left as f32 / right as f32;
    // Each side's count is binomial-like; sample elimination only makes it steadier.
    println!("{left} roots on the left at full density, {right} on the right at a quarter: ratio {ratio:.2}");
    assert!((ratio / 4.0 - 1.0).abs() < 0.15, "left {left} against right {right}");
    // Evenly: on the full-density side, no two roots nearer than half the spacing of hexagonal packing
    // (sample elimination reaches about 0.75 of it; random points come arbitrarily close).
    let spacing = |count: usize| (2.0 * hair_area / (3f32.sqrt() * count as f32)).sqrt();
    let left_roots: Vec<Vec3> = roots.iter().copied().filter(|p| p.x < -0.01).collect();
    let closest = nearest_neighbours(&left_roots).into_iter().fold(f32::MAX, f32::min);
    println!("closest roots {:.2} mm apart, hexagonal spacing {:.2} mm", 1e3 * closest, 1e3 * spacing(roots.len()));
    assert!(closest > 0.5 * spacing(roots.len()), "two roots {closest} m apart");
    // The guides are spread evenly among the roots too.
    let guide_roots: Vec<Vec3> = grown.iter().map(|(guide, _)| guide.nodes[0]).filter(|p| p.x < -0.01).collect();
    let closest_guides = nearest_neighbours(&guide_roots).into_iter().fold(f32::MAX, f32::min);
    assert!(closest_guides > 0.5 * spacing(guides), "two guides {closest_guides} m apart");
    // Every follower follows the guide whose root is nearest its own.
    let guide_roots: Vec<Vec3> = grown.iter().map(|(guide, _)| guide.nodes[0]).collect();
    for (guide, following) in &grown {
        for curve in &following.curves {
            let own = guide.nodes[0].distance(curve[0]);
            assert!(guide_roots.iter().all(|other| other.distance(curve[0]) >= own));
        }
    }
}

#[test]
fn hair_grown_on_a_scalp_mesh_keeps_to_its_hairline_and_lies_along_it_without_entering() {
    let mesh = scalp_cap(24, |_| [1.0; 4]);
    let surface = ScalpSurface::from_mesh(&mesh, Affine3A::IDENTITY).expect("the cap is a surface");
    let scalp = Scalp { nape_height: -0.2, brow_height: 0.5, ..default() };
    let combing = Combing::default();
    let grooms = [
        ("combed", HairGroom { strand_count: 300, scalp, combing: Some(combing), ..default() }),
        ("along the normal", HairGroom { strand_count: 300, scalp, combing: None, ..default() }),
    ];
    // The mesh lies inside the sphere by as much as its triangles' planes pass inside it.
    let positions = mesh.attribute(Mesh::ATTRIBUTE_POSITION).unwrap().as_float3().unwrap();
    let corners: Vec<usize> = mesh.indices().unwrap().iter().collect();
    let facets = corners
        .chunks(3)
        .filter_map(|t| {
            let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(positions[t[k]]));
            let normal = (b - a).cross(c - a).try_normalize()?;
            Some(RADIUS - a.dot(normal).abs())
        })
        .fold(0.0, f32::max)
        + 1e-6;
    for (label, groom) in grooms {
        let strands = groom.grow_on(Some(&surface)).expect("the groom grows");
        assert_eq!(strands.len(), 300, "{label}");
        for strand in &strands {
            let root = strand.nodes[0];
            // Inside the hairline: the nape's height everywhere, the brow's over the face (−z).
            let normal = root.normalize();
            assert!(normal.y >= scalp.nape_height - 0.02, "{label}: a root at height {}", normal.y);
            if -normal.z > 0.9 * normal.xz().length() {
                assert!(normal.y >= scalp.brow_height - 0.02, "{label}: a root over the face at {}", normal.y);
            }
            // Never inside the scalp.
            let deepest = strand.nodes.iter().map(|node| RADIUS - node.length()).fold(f32::MIN, f32::max);
            assert!(deepest <= facets, "{label}: a node {deepest} m inside the scalp");
        }
        if label == "combed" {
            // Combed hair leaves the scalp at its lift and lies along it: its second node within the
            // largest lift (and a millimetre) of the mesh.
            let highest = combing.lift + combing.layer_spread + 1e-3;
            for strand in strands.iter().filter(|strand| strand.nodes[0].y > 0.05) {
                let height = strand.nodes[2].length() - RADIUS;
                assert!(height <= highest, "combed hair stands {height} m off the scalp");
            }
        } else {
            // Grown along the normal: straight out from the root.
            for strand in &strands {
                let out = (strand.nodes[1] - strand.nodes[0]).normalize().dot(strand.nodes[0].normalize());
                assert!(out > 0.99, "a strand leaves at {out}");
            }
        }
    }
}

/// An app with meshes and transforms.
fn app_with_meshes() -> App {
    let mut app = hair_app_with((TransformPlugin, AssetPlugin::default()));
    app.init_asset::<Mesh>();
    app
}

#[test]
fn a_head_with_a_scalp_mesh_grows_its_groom_on_the_mesh_once_it_has_loaded() {
    let mut app = app_with_meshes();
    // The scalp mesh's handle before the mesh is there: the groom waits.
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().reserve_handle();
    let head_pose = Transform::from_xyz(0.3, 1.6, -0.2).with_rotation(Quat::from_rotation_y(0.7));
    let head = app.world_mut().spawn((head_pose, HairHead)).id();
    // The scalp is the head's child, 2 cm up.
    let lifted = Vec3::new(0.0, 0.02, 0.0);
    let scalp = app.world_mut().spawn((Mesh3d(mesh.clone()), Transform::from_translation(lifted), ChildOf(head))).id();
    app.world_mut().entity_mut(head).insert((HairScalpMesh(scalp), groom(60, 2)));
    for _ in 0..5 {
        app.update();
    }
    assert!(app.world().get::<HeadStrands>(head).is_none_or(|strands| strands.strands().is_empty()));
    assert!(matches!(app.world().get::<GroomSurface>(head), Some(GroomSurface::Waiting)));
    // It loads.
    app.world_mut().resource_mut::<Assets<Mesh>>().insert(mesh.id(), scalp_cap(16, |_| [1.0; 4])).unwrap();
    for _ in 0..3 {
        app.update();
    }
    let strands = app.world().get::<HeadStrands>(head).expect("the groom has grown").strands().to_vec();
    assert_eq!(strands.len(), 60);
    let surface = match app.world().get::<GroomSurface>(head) {
        Some(GroomSurface::Ready(surface)) => surface.clone(),
        _ => panic!("the surface is known"),
    };
    for &entity in &strands {
        // Grown on the mesh as it sits on the head (head-local), and bound to it.
        let root = app.world().get::<HairStrand>(entity).unwrap().nodes[0];
        assert!(((root - lifted).length() - RADIUS).abs() < 1e-3, "a root at {root}");
        assert!(surface.nearest(root).0.distance(root) < 1e-6);
        assert!(app.world().get::<ScalpRootBinding>(entity).is_some(), "a strand is not bound");
        let followers = app.world().get::<HairFollowers>(entity).unwrap();
        assert!(followers.curves.iter().all(|curve| surface.nearest(curve[0]).0.distance(curve[0]) < 1e-6));
        // Where the head is in the world.
        let world_root = strand(&app, entity).rod().positions()[0].as_vec3();
        assert!(world_root.distance(head_pose.transform_point(root)) < 1e-5);
    }
    let followers: usize =
        strands.iter().map(|&entity| app.world().get::<HairFollowers>(entity).unwrap().curves.len()).sum();
    assert_eq!(followers, 120);
}

/// A groom file of `strands`, each node written as `write` says.
fn groom_file(strands: &[HairStrand], write: impl Fn(Vec3) -> Vec3) -> GroomFile {
    let mut file = GroomFile { strand_starts: vec![0], ..default() };
    for strand in strands {
        file.points.extend(strand.nodes.iter().map(|&node| write(node)));
        file.strand_starts.push(file.points.len());
    }
    file
}

#[test]
fn a_groom_file_in_other_units_off_its_head_is_fitted_back_onto_the_scalp() {
    let mesh = scalp_cap(24, |_| [1.0; 4]);
    let surface = ScalpSurface::from_mesh(&mesh, Affine3A::IDENTITY).expect("the cap is a surface");
    // The groom as authored on this scalp, written in centimetres, 30 cm to the side and 150 cm up.
    let authored = groom(200, 0).grow_on(Some(&surface)).expect("the groom grows");
    let moved = Vec3::new(30.0, 150.0, -4.0);
    let file = groom_file(&authored, |node| 100.0 * node + moved);
    // Placed as it comes (one unit a metre), then fitted.
    let placement = GroomPlacement { fit_to_scalp: true, ..default() };
    let fitted = placement.fitted_to(&file, &surface);
    println!("fitted: {} m per unit, moved by {}", fitted.metres_per_unit, fitted.transform.translation);
    assert!((fitted.metres_per_unit / 0.01 - 1.0).abs() < 1e-3, "{} m per unit", fitted.metres_per_unit);
    let worst = authored
        .iter()
        .enumerate()
        .flat_map(|(index, strand)| {
            let placed = file.strand(index).iter().map(|&point| fitted.place(point)).collect::<Vec<_>>();
            strand.nodes.iter().zip(placed).map(|(node, placed)| node.distance(placed)).collect::<Vec<_>>()
        })
        .fold(0.0, f32::max);
    assert!(worst < 1e-4, "a fitted node {worst} m from where it was authored");
    // A crest of roots along the scalp's length only (a mohawk) is scaled by that length, not squashed.
    let crest: Vec<&HairStrand> = authored.iter().filter(|strand| strand.nodes[0].x.abs() < 0.01).collect();
    let crest: Vec<HairStrand> = crest.into_iter().cloned().collect();
    let mohawk = groom_file(&crest, |node| 100.0 * node + moved);
    let fitted = placement.fitted_to(&mohawk, &surface);
    let roots: Vec<Vec3> = (0..crest.len()).map(|index| fitted.place(mohawk.strand(index)[0])).collect();
    let off = roots.iter().map(|&root| surface.nearest(root).0.distance(root)).fold(0.0, f32::max);
    println!(
        "the crest fitted at {} m per unit, roots within {:.2} mm of the scalp",
        fitted.metres_per_unit,
        1e3 * off
    );
    assert!(off < 2e-3, "a crest root {off} m off the scalp");
    assert!((fitted.metres_per_unit / 0.01 - 1.0).abs() < 0.1, "{} m per unit", fitted.metres_per_unit);
}

#[test]
fn a_groom_file_on_a_head_with_a_scalp_mesh_is_moved_strand_by_strand_onto_it() {
    let mut app = app_with_meshes();
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(scalp_cap(16, |_| [1.0; 4]));
    // Strands authored 5 mm inside the scalp (another head's shape), each straight out and down.
    let authored: Vec<HairStrand> = (0..40)
        .map(|index| {
            let around = std::f32::consts::TAU * index as f32 / 40.0;
            let out = Vec3::new(0.6 * around.cos(), 0.8, 0.6 * around.sin());
            HairStrand::straight((RADIUS - 0.005) * out, out + Vec3::NEG_Y, 0.12, 8)
        })
        .collect();
    let file = app.world_mut().resource_mut::<Assets<GroomFile>>().add(groom_file(&authored, |node| node));
    let head = app.world_mut().spawn((HairHead, Transform::from_xyz(0.0, 1.5, 0.0))).id();
    let scalp = app.world_mut().spawn((Mesh3d(mesh), Transform::default(), ChildOf(head))).id();
    app.world_mut().entity_mut(head).insert((HairScalpMesh(scalp), HairGroomFile::new(file)));
    for _ in 0..4 {
        app.update();
    }
    let surface = match app.world().get::<GroomSurface>(head) {
        Some(GroomSurface::Ready(surface)) => surface.clone(),
        _ => panic!("the surface is known"),
    };
    let strands = app.world().get::<HeadStrands>(head).expect("placed").strands().to_vec();
    assert_eq!(strands.len(), 40);
    for entity in strands {
        let nodes = &app.world().get::<HairStrand>(entity).unwrap().nodes;
        let root = nodes[0];
        assert!(surface.nearest(root).0.distance(root) < 1e-6, "a root {root} off the scalp");
        // Moved whole: the same shape as authored, from a root on the scalp.
        let own = authored.iter().min_by(|a, b| {
            (a.nodes[1] - a.nodes[0])
                .angle_between(nodes[1] - root)
                .total_cmp(&(b.nodes[1] - b.nodes[0]).angle_between(nodes[1] - root))
        });
        let own = own.unwrap();
        let offset = root - own.nodes[0];
        assert!((offset.length() - 0.005).abs() < 1e-3, "moved {offset}");
        // (Resampled to the placement's edges: every node on the authored straight strand.)
        let (from, along) = (own.nodes[0], (own.nodes[8] - own.nodes[0]).normalize());
        let off_line = |node: Vec3| (node - offset - from).reject_from_normalized(along).length();
        assert!(nodes.iter().all(|&node| off_line(node) < 1e-5), "the strand's shape changed");
    }
}
