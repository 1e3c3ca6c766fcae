//! How a head of hair covers its scalp and holds together, measured headless: the figures a groom's look
//! in motion can be judged by without a picture. `cargo run --release --example benchmark coverage` prints
//! them for the example's scene at rest, shaking, turning and flicking.
//!
//! - **Scalp exposure** ([`scalp_exposure`]): the fraction of the haired scalp that the hair within a few
//!   millimetres of it does not hide, sampled at points spread evenly over the scalp as [`Scalp::roots`]
//!   spreads roots. A point is hidden when the hair drawn within `reach` of it, each hair a ribbon of its
//!   drawn width, covers at least the disc of radius `reach` around it (summed width × length inside the
//!   ball of `reach` ≥ π reach²). Every root has hair at it, so "any hair near" would hide every point; a
//!   bald patch is where the hair left, only the roots' first millimetres remaining.
//! - **Scalp seen** ([`scalp_seen`]): what a camera sees of the scalp through the hair. Of the same points,
//!   those facing the camera; each is seen when the hair in front of it, projected along the view as
//!   ribbons of its drawn width, covers less than the disc of a pixel about it. Hair lifted off the scalp
//!   hides it where it hangs in front; a bald patch is where the camera looks through. This is the
//!   figure the pictures are judged by.
//! - **Strays** ([`StrayCheck`]): the fraction of guides whose tip has left the tips of their neighbours
//!   (the guides rooted nearest them) by more than a set distance, counted from where it was at rest
//!   relative to them (a groom's parting or layers set tips apart at rest): single strands flying out.

use bevy::math::{Affine3A, IVec3, Vec3};
use bevy::platform::collections::HashMap;

use crate::groom::{GroomError, Scalp, ScalpRoot};

/// The fraction (0 to 1) of `scalp`'s haired surface the hair does not hide: `samples` points spread
/// evenly over the haired scalp ([`Scalp::roots`]), each hidden when the segments of `hairs` (each hair's
/// node positions, world space, root first, drawn `hair_width` m wide) within `reach` (m) of it cover the
/// disc of radius `reach` (see the [module documentation](self)). `head` takes the scalp's head-local space
/// to world space. Fails as [`Scalp::roots`] does.
pub fn scalp_exposure<'a>(
    scalp: &Scalp,
    head: &Affine3A,
    hairs: impl IntoIterator<Item = &'a [Vec3]>,
    samples: usize,
    (reach, hair_width): (f32, f32),
) -> Result<f32, GroomError> {
    let bare = bare_scalp(scalp, head, hairs, samples, (reach, hair_width))?;
    Ok(if bare.judged == 0 { 1.0 } else { bare.points.len() as f32 / bare.judged as f32 })
}

/// The points of the scalp [`scalp_exposure`] calls bare, to show where they are (a gizmo, a probe).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BareScalp {
    /// The bare points, head-local, each with the skull's outward normal there (as [`Scalp::roots`]
    /// gives them).
    pub points: Vec<ScalpRoot>,
    /// How many points were judged.
    pub judged: usize,
}

/// The points of `scalp` the hair leaves bare, judged as [`scalp_exposure`] judges them.
pub fn bare_scalp<'a>(
    scalp: &Scalp,
    head: &Affine3A,
    hairs: impl IntoIterator<Item = &'a [Vec3]>,
    samples: usize,
    (reach, hair_width): (f32, f32),
) -> Result<BareScalp, GroomError> {
    let roots = scalp.roots(samples)?;
    if roots.is_empty() || !(reach > 0.0 && reach.is_finite()) {
        return Ok(BareScalp { judged: roots.len(), points: roots });
    }
    let points: Vec<Vec3> = roots.iter().map(|root| head.transform_point3(root.position)).collect();
    let grid = PointGrid::new(&points, reach);
    // Per point, the length of hair within `reach` of it, m.
    let mut lengths = vec![0.0_f32; points.len()];
    for hair in hairs {
        for ends in hair.windows(2) {
            grid.add_lengths(ends[0], ends[1], reach, &points, &mut lengths);
        }
    }
    let judged = roots.len();
    let bare = roots.into_iter().zip(&lengths).filter(|&(_, &length)| uncovered(length, hair_width, reach));
    Ok(BareScalp { points: bare.map(|(root, _)| root).collect(), judged })
}

/// Whether `length` m of hair drawn `hair_width` m wide covers less than the disc of `radius` m.
fn uncovered(length: f32, hair_width: f32, radius: f32) -> bool {
    length * hair_width < std::f32::consts::PI * radius * radius
}

/// The share of points whose hair (`lengths`, m, drawn `hair_width` m wide) covers less than the disc of
/// `radius` about them.
fn uncovered_share(lengths: &[f32], hair_width: f32, radius: f32) -> f32 {
    let count = lengths.iter().filter(|&&length| uncovered(length, hair_width, radius)).count();
    count as f32 / lengths.len() as f32
}

/// The fraction (0 to 1) of the haired scalp a far camera looking along `-towards_camera` (world space)
/// sees through the hair: of `samples` points spread evenly over the haired scalp, those facing the camera
/// (their outward normal within 90° of `towards_camera`), the share whose line of sight the hair does not
/// hide. A point is hidden when the hair in front of it, drawn `hair_width` m wide and projected along the
/// view, covers at least the disc of radius `pixel` (m) around it on the picture (summed width × chord
/// through the disc ≥ π pixel²): what a picture of `pixel`-sized pixels would show as scalp. Unlike
/// [`scalp_exposure`], hair lifted away from the scalp still hides it where it lies in front. 0 when no
/// point faces the camera. Fails as [`Scalp::roots`] does.
pub fn scalp_seen<'a>(
    scalp: &Scalp,
    head: &Affine3A,
    hairs: impl IntoIterator<Item = &'a [Vec3]>,
    samples: usize,
    towards_camera: Vec3,
    (pixel, hair_width): (f32, f32),
) -> Result<f32, GroomError> {
    let facing: Vec<Vec3> = scalp
        .roots(samples)?
        .iter()
        .filter(|root| head.transform_vector3(root.normal).dot(towards_camera) > 0.0)
        .map(|root| head.transform_point3(root.position))
        .collect();
    Ok(if facing.is_empty() { 0.0 } else { share_seen(&facing, hairs, towards_camera, (pixel, hair_width)) })
}

/// The fraction (0 to 1) of `points` (world space) a far camera looking along `-towards_camera` sees
/// through `hairs` (each hair's node positions, drawn `hair_width` m wide): a point is hidden when the
/// hair in front of it, projected along the view, covers at least the disc of radius `pixel` (m) about it
/// on the picture, as in [`scalp_seen`]. Any surface can be judged this way, a face as well as a scalp.
/// 0 without points, a view or a positive `pixel`.
pub fn share_seen<'a>(
    points: &[Vec3],
    hairs: impl IntoIterator<Item = &'a [Vec3]>,
    towards_camera: Vec3,
    (pixel, hair_width): (f32, f32),
) -> f32 {
    let Some(depth_axis) = towards_camera.try_normalize() else { return 0.0 };
    if points.is_empty() || !(pixel > 0.0 && pixel.is_finite()) {
        return 0.0;
    }
    // The view's frame: the picture's two axes and the depth towards the camera.
    let (right, up) = depth_axis.any_orthonormal_pair();
    let to_view = |p: Vec3| Vec3::new(p.dot(right), p.dot(up), p.dot(depth_axis));
    let flat = |p: Vec3| Vec3::new(p.x, p.y, 0.0);
    let depths: Vec<f32> = points.iter().map(|&point| to_view(point).z).collect();
    let pictured: Vec<Vec3> = points.iter().map(|&point| flat(to_view(point))).collect();
    let grid = PointGrid::new(&pictured, pixel);
    let mut lengths = vec![0.0_f32; points.len()];
    for hair in hairs {
        for ends in hair.windows(2) {
            let (a, b) = (to_view(ends[0]), to_view(ends[1]));
            // Only the hair in front of a point hides it: the segment's depth where it passes the point.
            let in_front = |index: usize, along: f32| a.z + (b.z - a.z) * along.clamp(0.0, 1.0) > depths[index];
            grid.add_lengths_where(flat(a), flat(b), pixel, &pictured, &mut lengths, in_front);
        }
    }
    uncovered_share(&lengths, hair_width, pixel)
}

/// The sample points in cells of `reach`, to find those near a segment.
struct PointGrid {
    cell: f32,
    /// Per cell (by its integer coordinates), the indices of the points in it.
    cells: HashMap<IVec3, Vec<u32>>,
    low: Vec3,
    high: Vec3,
}

impl PointGrid {
    fn new(points: &[Vec3], reach: f32) -> Self {
        let mut cells: HashMap<IVec3, Vec<u32>> = HashMap::default();
        let (mut low, mut high) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for (index, point) in points.iter().enumerate() {
            cells.entry((*point / reach).floor().as_ivec3()).or_default().push(index as u32);
            (low, high) = (low.min(*point), high.max(*point));
        }
        Self { cell: reach, cells, low, high }
    }

    /// Adds to each point's length the length of the segment `a … b` within `reach` of it (the chord of
    /// the ball of radius `reach` about the point).
    fn add_lengths(&self, a: Vec3, b: Vec3, reach: f32, points: &[Vec3], lengths: &mut [f32]) {
        self.add_lengths_where(a, b, reach, points, lengths, |_, _| true);
    }

    /// [`PointGrid::add_lengths`] for the points `counts` accepts, given the point's index and the
    /// fraction of the way from `a` to `b` nearest it.
    fn add_lengths_where(
        &self,
        a: Vec3,
        b: Vec3,
        reach: f32,
        points: &[Vec3],
        lengths: &mut [f32],
        counts: impl Fn(usize, f32) -> bool,
    ) {
        let (low, high) = (a.min(b) - Vec3::splat(reach), a.max(b) + Vec3::splat(reach));
        // Most of a head's hair hangs away from its scalp: nothing to look up there.
        if low.cmpgt(self.high).any() || high.cmplt(self.low).any() || !(low.is_finite() && high.is_finite()) {
            return;
        }
        let (first, last) = ((low / self.cell).floor().as_ivec3(), (high / self.cell).floor().as_ivec3());
        let along = b - a;
        let length = along.length();
        if length <= 0.0 {
            return;
        }
        let direction = along / length;
        for x in first.x..=last.x {
            for y in first.y..=last.y {
                for z in first.z..=last.z {
                    let Some(indices) = self.cells.get(&IVec3::new(x, y, z)) else { continue };
                    for &index in indices {
                        // The line `a + s d` meets the ball where `(s − c)² ≤ reach² − h²`.
                        let offset = points[index as usize] - a;
                        let centre = offset.dot(direction);
                        let half_chord_squared = reach * reach - (offset.length_squared() - centre * centre);
                        if half_chord_squared > 0.0 && counts(index as usize, centre / length) {
                            let half_chord = half_chord_squared.sqrt();
                            let inside = (centre + half_chord).min(length) - (centre - half_chord).max(0.0);
                            lengths[index as usize] += inside.max(0.0);
                        }
                    }
                }
            }
        }
    }
}

/// Finds the guides that stray: those whose tip has moved more than a set distance from where it was at
/// rest relative to the mean tip of the guides rooted nearest them. Made once from a groom at rest, used
/// for any later pose.
#[derive(Debug, Clone)]
pub struct StrayCheck {
    /// Each guide's neighbours, `per_guide` indices per guide.
    neighbours: Vec<u32>,
    per_guide: usize,
    /// Each guide's tip at rest less its neighbours' mean tip, head-local, m.
    rest_offsets: Vec<Vec3>,
}

impl StrayCheck {
    /// Each guide of `roots` (head-local, m) gets its `neighbours` nearest others (fewer when there are not
    /// so many); `rest_tips` are the guides' tips at rest (world space, the head at `head`).
    pub fn new(roots: &[Vec3], neighbours: usize, head: &Affine3A, rest_tips: &[Vec3]) -> Self {
        let per_guide = neighbours.min(roots.len().saturating_sub(1));
        let mut lists = Vec::with_capacity(roots.len() * per_guide);
        let mut by_distance: Vec<(f32, u32)> = Vec::with_capacity(roots.len());
        for (index, root) in roots.iter().enumerate() {
            by_distance.clear();
            let others = roots.iter().enumerate().filter(|&(other, _)| other != index);
            by_distance.extend(others.map(|(other, position)| (position.distance_squared(*root), other as u32)));
            if per_guide > 0 {
                by_distance.select_nth_unstable_by(per_guide - 1, |a, b| a.0.total_cmp(&b.0));
            }
            lists.extend(by_distance[..per_guide].iter().map(|&(_, other)| other));
        }
        let mut check = Self { neighbours: lists, per_guide, rest_offsets: Vec::new() };
        check.rest_offsets = check.offsets(head, rest_tips);
        check
    }

    /// Each guide's tip less its neighbours' mean tip, head-local (empty if `tips` does not match).
    fn offsets(&self, head: &Affine3A, tips: &[Vec3]) -> Vec<Vec3> {
        if self.per_guide == 0 || tips.len() * self.per_guide != self.neighbours.len() {
            return Vec::new();
        }
        let to_local = head.inverse();
        let chunks = tips.iter().zip(self.neighbours.chunks_exact(self.per_guide));
        chunks
            .map(|(tip, neighbours)| {
                let mean = neighbours.iter().map(|&other| tips[other as usize]).sum::<Vec3>() / self.per_guide as f32;
                to_local.transform_vector3(*tip - mean)
            })
            .collect()
    }

    /// The fraction (0 to 1) of guides whose tip (world space, the head at `head`, in the order of the
    /// roots) has moved more than `distance` (m) from where it was at rest relative to its neighbours' mean
    /// tip; 0 without guides or neighbours.
    pub fn stray_fraction(&self, head: &Affine3A, tips: &[Vec3], distance: f32) -> f32 {
        let offsets = self.offsets(head, tips);
        if offsets.is_empty() || offsets.len() != self.rest_offsets.len() {
            return 0.0;
        }
        let strays = offsets.iter().zip(&self.rest_offsets).filter(|(now, rest)| now.distance(**rest) > distance);
        strays.count() as f32 / offsets.len() as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hairs lying on the scalp's surface along circles of latitude, `spacing` (rad) apart, over the part
    /// of the skull where `keep` holds.
    fn lying_hairs(scalp: &Scalp, spacing: f32, keep: impl Fn(Vec3) -> bool) -> Vec<Vec<Vec3>> {
        let mut hairs = Vec::new();
        let mut latitude = -std::f32::consts::FRAC_PI_2;
        while latitude <= std::f32::consts::FRAC_PI_2 {
            let hair: Vec<Vec3> = (0..=400)
                .map(|step| {
                    let longitude = step as f32 / 400.0 * std::f32::consts::TAU;
                    let direction =
                        Vec3::new(latitude.cos() * longitude.cos(), latitude.sin(), latitude.cos() * longitude.sin());
                    scalp.centre + direction * scalp.semi_axes * 1.02
                })
                .collect();
            for piece in hair.split(|point| !keep(*point)) {
                if piece.len() > 1 {
                    hairs.push(piece.to_vec());
                }
            }
            latitude += spacing;
        }
        hairs
    }

    #[test]
    fn exposure_is_the_share_of_the_scalp_the_hair_leaves_bare() {
        let scalp = Scalp::default();
        let head = Affine3A::from_translation(Vec3::new(0.3, 1.6, -0.1));
        let world = |hairs: &[Vec<Vec3>]| -> Vec<Vec<Vec3>> {
            hairs.iter().map(|hair| hair.iter().map(|p| head.transform_point3(*p)).collect()).collect()
        };
        let exposure = |hairs: &[Vec<Vec3>], width: f32| {
            let hairs = world(hairs);
            scalp_exposure(&scalp, &head, hairs.iter().map(Vec::as_slice), 2000, (0.004, width)).unwrap()
        };
        assert_eq!(exposure(&[], 1e-3), 1.0, "no hair: all of it bare");
        // Circles 2 mm apart along the surface (0.02 rad on a 10 cm skull), 2 mm above it: within 4 mm of
        // a point, 18 mm of hair or more (a chord of 6.9 mm and two of 5.7): hidden by ribbons 3 mm wide,
        // not by hairs of 0.1 mm.
        let everywhere = lying_hairs(&scalp, 0.02, |_| true);
        assert_eq!(exposure(&everywhere, 3e-3), 0.0);
        assert_eq!(exposure(&everywhere, 1e-4), 1.0, "too few hairs to hide the scalp");
        // Only over the skull's right half (x > 0): the left half of the haired scalp bare. The hairline
        // is symmetric about x = 0, so the bare share is a half, to the sampling's spread and the edge.
        let right = lying_hairs(&scalp, 0.02, |point| point.x > 0.0);
        let half = exposure(&right, 3e-3);
        assert!((half - 0.5).abs() < 0.03, "{half}");
        // The bare points are those of the left half, head-local, on the skull, one for each the share counts.
        let hairs = world(&right);
        let bare = bare_scalp(&scalp, &head, hairs.iter().map(Vec::as_slice), 2000, (0.004, 3e-3)).unwrap();
        assert_eq!((bare.points.len() as f32 / bare.judged as f32, bare.judged), (half, 2000));
        assert!(bare.points.iter().all(|root| root.position.x < 0.004 && (root.position.length() - 0.1).abs() < 1e-5));
        // Hair 2 cm above the scalp hides nothing within 4 mm.
        let far: Vec<Vec<Vec3>> = everywhere
            .iter()
            .map(|hair| hair.iter().map(|p| scalp.centre + (*p - scalp.centre) * 1.25).collect())
            .collect();
        assert_eq!(exposure(&far, 3e-3), 1.0);
    }

    #[test]
    fn a_camera_sees_the_scalp_the_hair_in_front_of_it_leaves_bare() {
        let scalp = Scalp::default();
        let head =
            Affine3A::from_rotation_translation(bevy::math::Quat::from_rotation_y(0.5), Vec3::new(0.3, 1.6, -0.1));
        let world = |hairs: &[Vec<Vec3>]| -> Vec<Vec<Vec3>> {
            hairs.iter().map(|hair| hair.iter().map(|p| head.transform_point3(*p)).collect()).collect()
        };
        // From behind the head (its +Z, turned with it), 2 mm pixels.
        let behind = head.transform_vector3(Vec3::Z);
        let seen = |hairs: &[Vec<Vec3>], width: f32, towards_camera: Vec3| {
            let hairs = world(hairs);
            scalp_seen(&scalp, &head, hairs.iter().map(Vec::as_slice), 2000, towards_camera, (0.002, width)).unwrap()
        };
        assert_eq!(seen(&[], 1e-3, behind), 1.0, "no hair: all of it seen");
        // Circles 2 mm apart lying on the skull: seen from behind, they cross the 2 mm disc about a point's
        // image with 4 mm of chord at least (one through its centre, or two 1 mm from it with 3.5 mm each;
        // more where the surface slopes away from the view and the circles crowd together), so 4 mm
        // ribbons hide it (π (2 mm)² / 4 mm = 3.1 mm of chord needed), 0.1 mm hairs do not.
        let everywhere = lying_hairs(&scalp, 0.02, |_| true);
        assert_eq!(seen(&everywhere, 4e-3, behind), 0.0);
        assert_eq!(seen(&everywhere, 1e-4, behind), 1.0, "too few hairs to hide the scalp");
        // The same hair lifted 2.5 cm off the scalp still hides it where it hangs in front of it (which the
        // nearby measure, `scalp_exposure`, calls bare).
        let lifted: Vec<Vec<Vec3>> = everywhere
            .iter()
            .map(|hair| hair.iter().map(|p| scalp.centre + (*p - scalp.centre) * 1.25).collect())
            .collect();
        assert_eq!(seen(&lifted, 4e-3, behind), 0.0);
        // Hair only on the far side of the head (z < 0, in front of the face, seen from behind): it lies
        // behind the scalp the camera sees, and hides none of it.
        let front = lying_hairs(&scalp, 0.02, |point| point.z < scalp.centre.z - 0.01);
        assert_eq!(seen(&front, 4e-3, behind), 1.0, "hair behind the scalp hides it");
        // Over the right half only (x > 0), seen from straight above (the hairline symmetric about x = 0):
        // half of what the camera sees is bare, to the sampling's spread and the edge.
        let right = lying_hairs(&scalp, 0.02, |point| point.x > 0.0);
        let half = seen(&right, 4e-3, head.transform_vector3(Vec3::Y));
        assert!((half - 0.5).abs() < 0.03, "{half}");
        assert_eq!(seen(&right, 4e-3, Vec3::ZERO), 0.0, "no view: nothing seen");
    }

    #[test]
    fn a_tip_that_leaves_its_neighbours_strays() {
        // A 10 × 10 patch of roots 5 mm apart, tips 20 cm below them, a parting down the middle at rest.
        let head = Affine3A::from_rotation_translation(bevy::math::Quat::from_rotation_y(0.7), Vec3::Y * 1.6);
        let roots: Vec<Vec3> =
            (0..100).map(|index| Vec3::new((index % 10) as f32, 0.0, (index / 10) as f32) * 0.005).collect();
        let parted = |root: &Vec3| *root + Vec3::new(if root.x < 0.024 { -0.1 } else { 0.1 }, -0.2, 0.0);
        let rest: Vec<Vec3> = roots.iter().map(|root| head.transform_point3(parted(root))).collect();
        let check = StrayCheck::new(&roots, 6, &head, &rest);
        assert_eq!(check.stray_fraction(&head, &rest, 0.03), 0.0, "at rest, parting and all");
        // The head turned: the hair turned with it.
        let turned = Affine3A::from_rotation_translation(bevy::math::Quat::from_rotation_y(-0.4), Vec3::Y * 1.6);
        let mut tips: Vec<Vec3> = roots.iter().map(|root| turned.transform_point3(parted(root))).collect();
        assert_eq!(check.stray_fraction(&turned, &tips, 0.03), 0.0, "moving as one");
        tips[45] += Vec3::new(0.0, 0.15, 0.05);
        // The flyaway itself; its neighbours' means move by a sixth of its 16 cm at most, under 3 cm.
        assert_eq!(check.stray_fraction(&turned, &tips, 0.03), 0.01);
        let alone = StrayCheck::new(&roots[..1], 6, &head, &rest[..1]);
        assert_eq!(alone.stray_fraction(&head, &tips[..1], 0.03), 0.0, "no neighbours");
    }
}
