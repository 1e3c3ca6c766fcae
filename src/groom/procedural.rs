//! Grooming: a whole head of hair from a few parameters. Put a [`HairGroom`] on a [`HairHead`] and the
//! plugin grows its strands (as [`HairStrand`]s rooted with [`StrandOf`]), and grows them anew whenever the
//! groom changes.
//!
//! [`HairHead`]: crate::simulation::HairHead

use std::f32::consts::{FRAC_PI_3, TAU};

use bevy::math::Affine3A;
use bevy::prelude::*;
use thiserror::Error;

use super::head_frame::{GroomFrame, HeadAxes};
use super::surface::{GroomSurface, ScalpSurface};
use crate::collision::mesh::MeshColliderError;
use crate::collision::{HairCollider, HeadColliders};
use crate::followers::HairFollowers;
use crate::rod::{ColliderShape, RigidPose};
use crate::simulation::{HairStrand, HeadStrands, StrandOf};
use crate::volume::RepresentedHairs;

/// The hair-bearing part of a head: an ellipsoid skull in the groom's frame (`−Z`, Bevy's forward, is the
/// face, `+Y` the crown; turned onto the head's [`HeadAxes`] and sized in metres whatever the head's
/// scale) and a hairline. Roots are spread over it along a golden-angle spiral, so they are evenly
/// spaced, without clumps or bald stripes.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct Scalp {
    /// Centre of the skull ellipsoid from the head's origin, m, along the groom's axes (`x` left to right,
    /// `y` up, `z` back).
    pub centre: Vec3,
    /// Semi-axes of the skull ellipsoid, m: half its width (x, ear to ear), height (y) and depth (z).
    /// Default 0.1 m each (a sphere).
    pub semi_axes: Vec3,
    /// Lowest hairline at the back and the sides, as the up component of the skull's surface normal
    /// (−1 at the bottom, 0 at the equator, 1 at the crown). Default −0.35 (the nape).
    pub nape_height: f32,
    /// Hairline over the face (the front, `−Z`), in the same measure. Default 0.45 (the brow).
    pub brow_height: f32,
}

impl Default for Scalp {
    fn default() -> Self {
        Self { centre: Vec3::ZERO, semi_axes: Vec3::splat(0.1), nape_height: -0.35, brow_height: 0.45 }
    }
}

/// A hair root on the scalp, head-local.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalpRoot {
    /// Position on the skull's surface, m.
    pub position: Vec3,
    /// Outward unit normal of the skull there: the direction the strand grows in.
    pub normal: Vec3,
}

impl Scalp {
    /// This scalp's hairline on the skull ellipsoid fitted to `points` (m, along the groom's axes: a head's
    /// vertices): the axis-aligned ellipsoid `A x² + B y² + C z² + D x + E y + F z = 1` nearest them by
    /// least squares (the algebraic fit: exact for points on an ellipsoid, whether they cover it or only
    /// its top, as a scalp does). Fails, naming why, with fewer than 9 points or points that no such
    /// ellipsoid fits (a plane, a saddle).
    pub fn fitted_to(&self, points: &[Vec3]) -> Result<Self, GroomError> {
        let unfit = |reason: &'static str| GroomError::ScalpFit { points: points.len(), reason };
        if points.len() < 9 {
            return Err(unfit("fewer than 9 points"));
        }
        // Centred and scaled to about unit size first, for the normal equations' conditioning.
        let mean = points.iter().map(|point| point.as_dvec3()).sum::<bevy::math::DVec3>() / points.len() as f64;
        let spread = points.iter().map(|point| (point.as_dvec3() - mean).length()).fold(0.0, f64::max);
        if !(spread.is_finite() && spread > 0.0) {
            return Err(unfit("the points are not finite and distinct"));
        }
        let mut normal = [[0.0_f64; 6]; 6];
        let mut right = [0.0_f64; 6];
        for point in points {
            let p = (point.as_dvec3() - mean) / spread;
            let row = [p.x * p.x, p.y * p.y, p.z * p.z, p.x, p.y, p.z];
            for i in 0..6 {
                right[i] += row[i];
                for j in 0..6 {
                    normal[i][j] += row[i] * row[j];
                }
            }
        }
        let [a, b, c, d, e, f] = solve_symmetric(normal, right).ok_or_else(|| unfit("they fit no quadric"))?;
        if !(a > 0.0 && b > 0.0 && c > 0.0) {
            return Err(unfit("they fit no ellipsoid"));
        }
        let centre = bevy::math::DVec3::new(-d / (2.0 * a), -e / (2.0 * b), -f / (2.0 * c));
        let level = 1.0 + a * centre.x * centre.x + b * centre.y * centre.y + c * centre.z * centre.z;
        let semi_axes = bevy::math::DVec3::new((level / a).sqrt(), (level / b).sqrt(), (level / c).sqrt()) * spread;
        let fitted = Self { centre: (mean + centre * spread).as_vec3(), semi_axes: semi_axes.as_vec3(), ..*self };
        fitted.validate().map_err(|_| unfit("they fit no ellipsoid"))?;
        Ok(fitted)
    }

    /// `count` roots spread evenly over the scalp: the points of a golden-angle spiral over the whole
    /// skull that fall inside the hairline, with the spiral's length chosen so that at least `count` do
    /// (the few extra are dropped evenly along the spiral). Fails if the hairline leaves less than 0.1 %
    /// of the skull.
    pub fn roots(&self, count: usize) -> Result<Vec<ScalpRoot>, GroomError> {
        self.validate()?;
        // The spiral of `total` points holds `inside(total)` roots; find the shortest that holds `count`.
        let inside = |total: usize| (0..total).filter(|&index| self.spiral_root(index, total).is_some()).count();
        if inside(10_000) < 10 {
            return Err(GroomError::EmptyScalp { nape_height: self.nape_height, brow_height: self.brow_height });
        }
        if count == 0 {
            return Ok(Vec::new());
        }
        let mut longest = count;
        while inside(longest) < count {
            longest *= 2;
        }
        let mut shortest = count;
        while shortest < longest {
            let middle = (shortest + longest) / 2;
            if inside(middle) >= count { longest = middle } else { shortest = middle + 1 }
        }
        let mut roots: Vec<ScalpRoot> = (0..longest).filter_map(|index| self.spiral_root(index, longest)).collect();
        let (found, surplus) = (roots.len(), roots.len() - count);
        for dropped in (0..surplus).rev() {
            roots.remove((2 * dropped + 1) * found / (2 * surplus));
        }
        Ok(roots)
    }

    /// Point `index` of a golden-angle spiral of `total` points over the skull, if it lies inside the
    /// hairline.
    fn spiral_root(&self, index: usize, total: usize) -> Option<ScalpRoot> {
        const GOLDEN_ANGLE: f32 = 2.399_963_2;
        let height = 1.0 - 2.0 * (index as f32 + 0.5) / total as f32;
        let ring = (1.0 - height * height).max(0.0).sqrt();
        let around = GOLDEN_ANGLE * index as f32;
        let root = self.on_skull(Vec3::new(ring * around.cos(), height, ring * around.sin()));
        self.grows_hair_at(root.normal).then_some(root)
    }

    /// The hairline's height in the direction of `normal` (the skull's outward unit normal, head-local),
    /// as the up component of the normal: the brow's over the face, blending into the nape's over the
    /// temples. Hair grows where `normal.y` is at least this.
    pub fn hairline_height(&self, normal: Vec3) -> f32 {
        let horizontal = Vec2::new(normal.x, -normal.z);
        let facing_front = if horizontal.length_squared() > 1e-12 { horizontal.normalize().y } else { 0.0 };
        let face = ((facing_front - 0.3) / 0.4).clamp(0.0, 1.0);
        let face = face * face * (3.0 - 2.0 * face);
        self.nape_height + (self.brow_height - self.nape_height) * face
    }

    /// Whether hair grows where the skull's outward unit normal (head-local) is `normal`: inside the
    /// hairline, where `normal.y` is at least [`Scalp::hairline_height`].
    pub fn grows_hair_at(&self, normal: Vec3) -> bool {
        normal.y >= self.hairline_height(normal)
    }

    /// How far inside the hairline the point of the skull radially under `position` (head-local) lies, m,
    /// along the skull; negative outside. To first order: the hairline's margin there
    /// (`normal.y − hairline_height`) over how fast it changes along the skull (by central differences
    /// 1 mm apart), so it is close near the hairline and grows without bound towards the crown.
    pub fn depth_inside_hairline(&self, position: Vec3) -> f32 {
        const STEP: f32 = 0.001;
        let margin_at = |normal: Vec3| normal.y - self.hairline_height(normal);
        let margin = |point: Vec3| margin_at(self.radially_under(point).normal);
        let ScalpRoot { position: point, normal } = self.radially_under(position);
        let (across, along) = normal.any_orthonormal_pair();
        let slope =
            |direction: Vec3| (margin(point + STEP * direction) - margin(point - STEP * direction)) / (2.0 * STEP);
        let gradient = Vec2::new(slope(across), slope(along)).length();
        let here = margin_at(normal);
        if gradient > 0.0 { here / gradient } else { here.signum() * f32::INFINITY }
    }

    /// The point of the skull radially under `point` (from the centre), with the outward unit normal there.
    fn radially_under(&self, point: Vec3) -> ScalpRoot {
        self.on_skull(((point - self.centre) / self.semi_axes).normalize_or(Vec3::Y))
    }

    /// The point of the skull that `on_unit_sphere` (a unit vector) scales to, with the outward unit
    /// normal there.
    fn on_skull(&self, on_unit_sphere: Vec3) -> ScalpRoot {
        let normal = (on_unit_sphere / self.semi_axes).normalize();
        ScalpRoot { position: self.centre + self.semi_axes * on_unit_sphere, normal }
    }

    fn validate(&self) -> Result<(), GroomError> {
        if !self.centre.is_finite() || !self.semi_axes.is_finite() || self.semi_axes.min_element() <= 0.0 {
            return Err(GroomError::Skull { centre: self.centre, semi_axes: self.semi_axes });
        }
        for (name, height) in [("nape", self.nape_height), ("brow", self.brow_height)] {
            if !(-1.0..=1.0).contains(&height) {
                return Err(GroomError::Hairline { name, height });
            }
        }
        Ok(())
    }
}

/// The shape hair grows in. Each style spawns strands whose shape is their rest shape, so waves and curls
/// are kept while the hair moves; lengths vary per strand within the style's range
/// ([`HairStyle::length_range`]).
#[derive(Reflect, Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
#[reflect(Debug, Default, Clone, PartialEq, Hash)]
pub enum HairStyle {
    /// Straight hair, 14 to 22 cm: falls under its weight.
    #[default]
    Straight,
    /// Hair in gentle planar waves (wavelength 6 cm, amplitude about 5 mm), 16 to 24 cm.
    Wavy,
    /// Helical curls of radius 6 mm (never less than one edge, so they stay resolved), 14 to 22 cm of
    /// fibre.
    Curly,
    /// Short straight hair, 3 to 6 cm: combed, it lies along the scalp all the way; uncombed, it is stiff
    /// enough to stand out from it.
    Short,
    /// Long straight hair, 32 to 45 cm: hangs.
    Long,
}

impl HairStyle {
    /// Every style, for menus.
    pub const ALL: [HairStyle; 5] = [Self::Straight, Self::Wavy, Self::Curly, Self::Short, Self::Long];

    /// Shortest and longest strand of the style, m (length along the fibre).
    pub fn length_range(self) -> (f32, f32) {
        match self {
            Self::Straight | Self::Curly => (0.14, 0.22),
            Self::Wavy => (0.16, 0.24),
            Self::Short => (0.03, 0.06),
            Self::Long => (0.32, 0.45),
        }
    }

    /// The style's name, for menus.
    pub fn name(self) -> &'static str {
        match self {
            Self::Straight => "straight",
            Self::Wavy => "wavy",
            Self::Curly => "curly",
            Self::Short => "short",
            Self::Long => "long",
        }
    }
}

/// The most edges per strand a groom grows (a [`HairGroom`], or a groom file's [`GroomPlacement`]):
/// far more than real-time hair uses (16 to 32), and a bound on what one strand costs.
///
/// [`GroomPlacement`]: crate::groom::GroomPlacement
pub const MAX_GROOM_SEGMENTS: usize = 1024;

/// The most hairs a [`HairGroom`] grows, strands and their followers together: several heads of human
/// hair (90 000 to 150 000 hairs each).
pub const MAX_GROOM_HAIRS: usize = 1_000_000;

/// Grows a head of hair: put it on a [`crate::simulation::HairHead`] and the plugin spawns `strand_count`
/// strands of `style` over `scalp`, each marked [`GroomedStrand`]. Changing the groom despawns the
/// groomed strands and grows new ones (strands you spawned yourself on the head are kept). An invalid
/// groom is reported with an error message and the head keeps its hair.
///
/// Every length in a groom is metres, and its directions are the groom's design axes (the face `−Z`, the
/// crown `+Y`), whatever the head's rig: the groom is grown on its head turned onto the head's
/// [`HeadAxes`] and sized by the head's scale, so the same groom looks the same on a head modelled in
/// centimetres and spawned at a scale of 0.01, or on a joint whose face looks along `+X`.
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct HairGroom {
    /// Where hair grows.
    pub scalp: Scalp,
    /// Which way the head's face and crown point in its local space (its rig's own axes). Default: the
    /// face `−Z`, the crown `+Y`.
    pub head_axes: HeadAxes,
    /// Number of strands (with their followers at most [`MAX_GROOM_HAIRS`]). Default 2 000.
    pub strand_count: usize,
    /// Edges per strand (nodes are one more), from 2 to [`MAX_GROOM_SEGMENTS`]. More edges resolve curls
    /// better and cost proportionally more. Default 24.
    pub segments: usize,
    /// Shape and lengths of the hair.
    pub style: HairStyle,
    /// Seed of the per-strand variation (lengths, curl phases): the same seed grows the same hair.
    pub seed: u64,
    /// How the hair is combed: `Some` lays each strand along the scalp from its root, away from a parting
    /// and back from the face, down to the hairline, and lets the rest fall from there in the style's
    /// shape; `None` grows each strand straight out along the scalp's normal. Default: combed.
    pub combing: Option<Combing>,
    /// Follower hairs per simulated strand (see [`crate::followers`]): each guide strand carries this
    /// many unsimulated hairs with roots of their own, spread evenly between the guides' roots, each in
    /// its guide's shape moved onto its root, placed from the guide's motion every step. 0 (the default)
    /// simulates every hair drawn.
    pub followers_per_guide: usize,
    /// How much followers gather onto their guide towards the tip, 0 to 1 (see
    /// [`HairFollowers::clumping`]). Default 0.4: a wisp's tips gather to 0.6 of its spread at the root, so
    /// that its ends taper instead of ending as one flat-edged lock; 0 keeps each follower its guide's
    /// groomed shape, moved onto its own root.
    pub follower_clumping: f32,
    /// How much each follower's clumping differs from `follower_clumping`, 0 to 1 (see
    /// [`HairFollowers::clumping_variation`]). Default 0.5.
    pub follower_clumping_variation: f32,
    /// How far a follower strays from its place around the guide towards its tip, m, drawn per follower
    /// (see [`HairFollowers::scatter`]). Default 0.004: up to 4 mm at the tip.
    pub follower_scatter: f32,
    /// Hairs on the head the groom stands for, in the hair's volume ([`crate::volume`]): each strand is
    /// counted as `hair_count / strand_count` hairs (at least itself and its followers; see
    /// [`RepresentedHairs`]). A human head has 90 000 to 150 000 hairs. Default 100 000.
    pub hair_count: usize,
    /// Gravity preload of every strand, 0 to 1 (see [`HairStrand::gravity_preload`]): 1 makes the grown
    /// shape the shape at rest under gravity, lying on the skull collider where it was combed onto it; 0
    /// lets it sag. Default 1.
    pub gravity_preload: f32,
    /// Width of the band inside the hairline over which the drawn hair thins out, m, measured along the
    /// skull ([`Scalp::depth_inside_hairline`]): a hair rooted at the hairline is drawn
    /// [`HAIRLINE_THINNEST`] as wide, and only [`HAIRLINE_SPARSEST`] of the hairs there are drawn at all,
    /// both rising smoothly to the whole `hairline_fade` inside, as a real hairline's fine single hairs
    /// thin into bare skin. Given to the strands as [`StrandWidths`]; only the drawing changes, not the
    /// simulation. A groom grown on a scalp mesh is judged on the [`Scalp`]'s ellipsoid radially under
    /// each root, so the fade follows the mesh's hairline as closely as the ellipsoid fits the head.
    /// 0: a hard hairline. Default 0.008.
    pub hairline_fade: f32,
}

/// How wide a hair rooted right at the hairline is drawn, as a share of its width inside
/// ([`HairGroom::hairline_fade`]).
pub const HAIRLINE_THINNEST: f32 = 0.35;

/// The share of the hairs rooted right at the hairline that are drawn ([`HairGroom::hairline_fade`]).
pub const HAIRLINE_SPARSEST: f32 = 0.3;

/// The share (0 to 1) of its strand's drawn width each hair of a strand is drawn with: the guide's, then
/// each of its followers' in the order of its [`HairFollowers::curves`]; 0 leaves the hair out. A head's
/// [`HairGroom`] gives it to the strands it grows by its hairline ([`HairGroom::hairline_fade`]); give it to
/// strands of your own to thin their hair. The renderer reads it when it lays the head's hair out (when the
/// strands are spawned or change); a hair it has no share for is drawn whole.
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct StrandWidths {
    /// Per drawn hair (the guide first): its share of the strand's width, 0 to 1.
    pub hairs: Vec<f32>,
}

impl Default for HairGroom {
    fn default() -> Self {
        Self {
            scalp: Scalp::default(),
            head_axes: HeadAxes::default(),
            strand_count: 2000,
            segments: 24,
            style: HairStyle::Straight,
            seed: 0,
            combing: Some(Combing::default()),
            followers_per_guide: 0,
            follower_clumping: 0.4,
            follower_clumping_variation: 0.5,
            follower_scatter: 0.004,
            hair_count: 100_000,
            gravity_preload: 1.0,
            hairline_fade: 0.008,
        }
    }
}

/// How a [`HairGroom`] is combed (all head-local). Hair is laid along the scalp in the direction of a
/// combing field: away from the parting line, back from the face and the crown, and down; from the
/// skull's upper sides on straight down (where the weight of the hair hanging from it would slide it to),
/// so that the hair covers the scalp down to its hairline. There, or where the combing turns back on
/// itself, a strand leaves the scalp and falls. Short hair lies on past the hairline, until the skull
/// turns under it.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct Combing {
    /// Sideways position of the parting line, m, from the skull's centre along +x (the head's right
    /// for a face looking along −Z). Default 0.02 (a side parting).
    pub parting: f32,
    /// How strongly hair in front is combed back from the face, dimensionless (0: only sideways and
    /// down; 1: back as much as sideways). Default 1.2.
    pub sweep_back: f32,
    /// Height of the lowest layer of hair over the skull, m: just above the strands' collision thickness
    /// (their radius plus [`crate::simulation::HairSettings::collision_margin`], 1.04 mm by default), so
    /// that groomed hair starts out resting on the skull. Hair groomed higher drops onto it when
    /// simulated, and near a parting, where its preloaded shape balances on the skull's slope, that drop
    /// can tip it over to the other side. Default 0.00106.
    pub lift: f32,
    /// How much higher the highest layer lies, m: each strand's lift is spread over this. Default 0.0004.
    pub layer_spread: f32,
    /// How strongly hair on top of the head is combed back, dimensionless, fading out towards the sides
    /// (as the square of the scalp's normal's up component). 0 combs it only sideways there, so that the
    /// parting opens into a bare stripe across the crown; 0.6 (the default) combs it back along the
    /// parting, covering the line with the hair rooted before it.
    pub crown_sweep: f32,
    /// How far from the parting hair is combed fully sideways, m: nearer, less (in proportion), so that
    /// hair rooted at the parting runs along it for a while (back from the face and the crown) instead of
    /// leaving it at once, and the parting shows as a line where the hair turns, not a bare stripe.
    /// Default 0.03.
    pub parting_blend: f32,
    /// How strongly hair at the front of the parting is combed back along it, dimensionless: added to
    /// the sweep back in full on the parting line, fading out over `parting_blend` to either side and
    /// with the square of how squarely the scalp faces the front. On the forehead, "back" lies mostly
    /// along the skull's normal, so the plain sweep back leaves the hair there running sideways off the
    /// line and the parting's first centimetres bare; this runs the hair rooted at the front of the
    /// parting back over the line behind it. Default 4.
    pub parting_sweep: f32,
}

impl Default for Combing {
    fn default() -> Self {
        Self {
            parting: 0.02,
            sweep_back: 1.2,
            lift: 0.00106,
            layer_spread: 0.0004,
            crown_sweep: 0.6,
            parting_blend: 0.03,
            parting_sweep: 4.0,
        }
    }
}

impl HairGroom {
    /// The strands of this groom, in the head's local space: combed along the scalp (see [`Combing`]), or,
    /// without combing, each growing out along the scalp's normal.
    pub fn grow(&self) -> Result<Vec<HairStrand>, GroomError> {
        self.grow_on(None)
    }

    /// The strands of this groom grown on `surface` (a scalp mesh) if given, else on the [`Scalp`]'s
    /// ellipsoid: see [`HairGroom::grow_with_followers_on`].
    pub fn grow_on(&self, surface: Option<&ScalpSurface>) -> Result<Vec<HairStrand>, GroomError> {
        let without_followers = Self { followers_per_guide: 0, ..self.clone() };
        Ok(without_followers.grow_with_followers_on(surface)?.into_iter().map(|(strand, _)| strand).collect())
    }

    /// How many hairs each strand stands for: its share of [`HairGroom::hair_count`], at least itself
    /// and its followers.
    pub fn hairs_per_strand(&self) -> u32 {
        let share = (self.hair_count as f64 / self.strand_count.max(1) as f64).round();
        (share as u32).max(1 + self.followers_per_guide as u32)
    }

    /// The guide strands of this groom with their followers ([`HairGroom::followers_per_guide`]): the
    /// roots of `strand_count × (1 + followers_per_guide)` hairs spread evenly over the scalp, every
    /// `1 + followers_per_guide`-th of them a guide, the others each following the guide whose root is
    /// nearest.
    pub fn grow_with_followers(&self) -> Result<Vec<(HairStrand, HairFollowers)>, GroomError> {
        self.grow_with_followers_on(None)
    }

    /// The guide strands of this groom with their followers, grown on `surface` if given: the roots of
    /// `strand_count × (1 + followers_per_guide)` hairs spread evenly over it by area times its density,
    /// inside the [`Scalp`]'s hairline (judged by the surface's normal), `strand_count` of them, spread
    /// evenly too, guides; the hair leaves the surface along its normal, or combed along it, measuring the
    /// parting from [`Scalp::centre`]. Without a surface, as [`HairGroom::grow_with_followers`].
    pub fn grow_with_followers_on(
        &self,
        surface: Option<&ScalpSurface>,
    ) -> Result<Vec<(HairStrand, HairFollowers)>, GroomError> {
        self.grow_with_followers_around(surface, &GroomObstacles::default())
    }

    /// [`HairGroom::grow_with_followers_on`], the falling hair draped over `obstacles` (the body under the
    /// head: shoulders, back, chest) instead of passing through them: a falling strand bends as it nears
    /// one, lies on its surface a [`Combing::lift`] above it and slides down along it. The plugin grows a
    /// head's groom around the colliders tied to the head when the groom grows.
    pub fn grow_with_followers_around(
        &self,
        surface: Option<&ScalpSurface>,
        obstacles: &GroomObstacles,
    ) -> Result<Vec<(HairStrand, HairFollowers)>, GroomError> {
        self.validate()?;
        // Grown along the design's axes, then turned onto the head's.
        let frame = GroomFrame { rotation: self.head_axes.rotation()?, scale: 1.0 };
        if !frame.is_identity() {
            let surface =
                surface.map(|surface| surface.mapped(|position| frame.point_in_frame(position))).transpose()?;
            let designed = Self { head_axes: HeadAxes::default(), ..self.clone() };
            let mut grown =
                designed.grow_with_followers_around(surface.as_ref(), &obstacles.seen_turned_by(frame.rotation))?;
            frame.grown_to_head(&mut grown);
            return Ok(grown);
        }
        let every = 1 + self.followers_per_guide;
        let mut random = fastrand::Rng::with_seed(self.seed);
        let (guide_roots, follower_roots) = match surface {
            Some(surface) => surface.guide_and_follower_roots(self.strand_count, every, &self.scalp, &mut random)?,
            None => {
                let roots = self.scalp.roots(self.strand_count.saturating_mul(every))?;
                let (guides, followers): (Vec<_>, Vec<_>) =
                    roots.into_iter().enumerate().partition(|(index, _)| index % every == 0);
                (
                    guides.into_iter().map(|(_, root)| root).collect(),
                    followers.into_iter().map(|(_, root)| root).collect(),
                )
            }
        };
        let mut random = fastrand::Rng::with_seed(self.seed);
        let mut grown: Vec<(HairStrand, HairFollowers)> = Vec::with_capacity(guide_roots.len());
        for &root in &guide_roots {
            let followers = HairFollowers {
                clumping: self.follower_clumping,
                clumping_variation: self.follower_clumping_variation,
                scatter: self.follower_scatter,
                ..HairFollowers::default()
            };
            grown.push((self.grow_strand(root, surface, obstacles, &mut random), followers));
        }
        // A follower is its guide's shape moved onto its own root: grown on its own, it would leave its guide
        // (another length, the other side of a shoulder, the other way round a parting) by centimetres,
        // and its offset, carried in the guide's turning frame, swings it far from the hair when the guide
        // twists.
        for root in follower_roots {
            let nearest = guide_roots.iter().enumerate().min_by(|a, b| {
                a.1.position.distance_squared(root.position).total_cmp(&b.1.position.distance_squared(root.position))
            });
            if let Some((guide, guide_root)) = nearest {
                let curve =
                    grown[guide].0.nodes.iter().map(|&node| root.position + (node - guide_root.position)).collect();
                grown[guide].1.curves.push(curve);
            }
        }
        Ok(grown)
    }

    /// How wide each hair of `grown` (as [`HairGroom::grow_with_followers`] grows it) is drawn, by how far
    /// inside the hairline its root lies ([`HairGroom::hairline_fade`]): one [`StrandWidths`] per strand,
    /// its guide's share first. Which of the hairs near the hairline are left out is drawn from the
    /// groom's seed: the same groom thins the same hairs.
    pub fn hairline_widths(&self, grown: &[(HairStrand, HairFollowers)]) -> Vec<StrandWidths> {
        let mut random = fastrand::Rng::with_seed(self.seed ^ 0x6861_6972_6c69_6e65);
        // The roots along the groom's axes.
        let to_design = self.head_axes.rotation().unwrap_or(Quat::IDENTITY).inverse();
        let mut share = |root: Option<&Vec3>| {
            let drawn = random.f32();
            let Some(&root) = root.filter(|_| self.hairline_fade > 0.0) else { return 1.0 };
            let root = if to_design == Quat::IDENTITY { root } else { to_design * root };
            let inside = (self.scalp.depth_inside_hairline(root) / self.hairline_fade).clamp(0.0, 1.0);
            let smooth = inside * inside * (3.0 - 2.0 * inside);
            let kept = drawn < HAIRLINE_SPARSEST + (1.0 - HAIRLINE_SPARSEST) * smooth;
            if kept { HAIRLINE_THINNEST + (1.0 - HAIRLINE_THINNEST) * smooth } else { 0.0 }
        };
        grown
            .iter()
            .map(|(strand, followers)| {
                let roots =
                    std::iter::once(strand.nodes.first()).chain(followers.curves.iter().map(|curve| curve.first()));
                StrandWidths { hairs: roots.map(&mut share).collect() }
            })
            .collect()
    }

    fn validate(&self) -> Result<(), GroomError> {
        if self.segments < 2 {
            return Err(GroomError::TooFewSegments(self.segments));
        }
        if self.segments > MAX_GROOM_SEGMENTS {
            return Err(GroomError::TooManySegments(self.segments));
        }
        let hairs = self.strand_count.checked_mul(self.followers_per_guide.saturating_add(1));
        if hairs.is_none_or(|hairs| hairs > MAX_GROOM_HAIRS) {
            return Err(GroomError::TooManyHairs {
                strand_count: self.strand_count,
                followers_per_guide: self.followers_per_guide,
            });
        }
        if !(0.0..=1.0).contains(&self.gravity_preload) {
            return Err(GroomError::GravityPreload(self.gravity_preload));
        }
        if !(0.0..=1.0).contains(&self.follower_clumping) {
            return Err(GroomError::FollowerClumping(self.follower_clumping));
        }
        if !(0.0..=1.0).contains(&self.follower_clumping_variation) {
            return Err(GroomError::FollowerClumpingVariation(self.follower_clumping_variation));
        }
        if !(self.follower_scatter >= 0.0 && self.follower_scatter.is_finite()) {
            return Err(GroomError::FollowerScatter(self.follower_scatter));
        }
        if !(self.hairline_fade >= 0.0 && self.hairline_fade.is_finite()) {
            return Err(GroomError::HairlineFade(self.hairline_fade));
        }
        if let Some(combing) = &self.combing {
            combing.validate()?;
        }
        Ok(())
    }

    /// One strand of this groom from `root`, in the head's local space, combed along `surface` if given,
    /// else along the scalp's ellipsoid.
    fn grow_strand(
        &self,
        root: ScalpRoot,
        surface: Option<&ScalpSurface>,
        obstacles: &GroomObstacles,
        random: &mut fastrand::Rng,
    ) -> HairStrand {
        let (shortest, longest) = self.style.length_range();
        let length = shortest + (longest - shortest) * random.f32();
        let edge_length = length / self.segments as f32;
        let strand = match &self.combing {
            Some(combing) => {
                let lift = combing.lift + combing.layer_spread * random.f32();
                let path = CombedPath { scalp: &self.scalp, surface, obstacles, combing, lift };
                let (nodes, material_direction) = path.grow(root, self.style, length, self.segments, random);
                HairStrand::from_nodes(nodes, material_direction)
            }
            None => {
                let shape = StrandShape::new(self.style, root.normal, edge_length, random);
                let mut nodes = Vec::with_capacity(self.segments + 1);
                let mut node = root.position;
                nodes.push(node);
                for edge in 0..self.segments {
                    node += shape.edge(edge);
                    nodes.push(node);
                }
                HairStrand::from_nodes(nodes, shape.down_the_scalp)
            }
        };
        strand.with_gravity_preload(self.gravity_preload)
    }
}

/// Shapes a groom's falling hair drapes over instead of passing through: the body under a head, in the
/// head's local space (see [`HairGroom::grow_with_followers_around`]). The plugin makes them from the
/// [`HairCollider`]s tied to the head when its groom grows.
#[derive(Debug, Clone, Default)]
pub struct GroomObstacles {
    shapes: Vec<(ColliderShape, RigidPose)>,
}

impl GroomObstacles {
    /// Obstacles from shapes placed in the head's local space (each shape in its own frame, `pose` taking
    /// that frame to the head's). Shapes that fail [`ColliderShape::validate`] are left out.
    pub fn new(shapes: impl IntoIterator<Item = (ColliderShape, RigidPose)>) -> Self {
        Self { shapes: shapes.into_iter().filter(|(shape, _)| shape.validate().is_ok()).collect() }
    }

    /// The colliders tied to `head` ([`HeadColliders`]) in its local space, as they are placed now, sized in
    /// metres when the head is scaled (`scaled`: its scale taken out, as [`GroomFrame`] grows hair).
    fn of_head(
        head: Entity,
        scaled: bool,
        colliders: &Query<&HeadColliders>,
        shapes: &Query<&HairCollider>,
        transforms: &TransformHelper,
    ) -> Self {
        let Ok(head_transform) = transforms.compute_global_transform(head) else { return Self::default() };
        let to_head = if scaled {
            let (_, rotation, translation) = head_transform.to_scale_rotation_translation();
            Affine3A::from_rotation_translation(rotation, translation).inverse()
        } else {
            head_transform.affine().inverse()
        };
        let own = colliders.get(head).map(HeadColliders::colliders).unwrap_or_default();
        Self::new(own.iter().filter_map(|&entity| {
            let collider = shapes.get(entity).ok()?;
            let transform = transforms.compute_global_transform(entity).ok()?;
            Some(collider.placed(&GlobalTransform::from(to_head * transform.affine())))
        }))
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }

    /// These obstacles seen from a frame turned by `rotation` from the one they are placed in.
    fn seen_turned_by(&self, rotation: Quat) -> Self {
        let inverse = rotation.inverse().as_dquat();
        let shapes = self.shapes.iter().map(|(shape, pose)| {
            (shape.clone(), RigidPose::new((inverse * pose.rotation).normalize(), inverse * pose.translation))
        });
        Self { shapes: shapes.collect() }
    }

    /// Of the obstacles that do not hold `root` (a hair grows out of the shapes its root is in), the one
    /// whose surface grown by `clearance` is nearest `point` (head-local), if less than `reach` m outside
    /// it: how far outside that surface `point` is (m, negative inside), and its outward normal there.
    fn nearest(&self, point: Vec3, clearance: f32, reach: f32, root: Vec3) -> Option<(f32, Vec3)> {
        let within_reach = self.shapes.iter().filter_map(|(shape, pose)| {
            let grown = shape.inflated(f64::from(clearance));
            let (local, root) = (pose.to_local(point.as_dvec3()), pose.to_local(root.as_dvec3()));
            let gap = grown.distance_bound(local);
            (gap < f64::from(reach) && !grown.contains(root)).then(|| {
                let surface = grown.closest_surface_point(local);
                let normal = (pose.rotation * surface.normal).as_vec3();
                // Outside, the distance bound; inside, the depth below the nearest surface point.
                let gap = if gap >= 0.0 { gap as f32 } else { -(surface.point - local).length() as f32 };
                (gap, normal)
            })
        });
        within_reach.min_by(|a, b| a.0.total_cmp(&b.0))
    }
}

impl Combing {
    fn validate(&self) -> Result<(), GroomError> {
        let values = [
            self.parting,
            self.sweep_back,
            self.lift,
            self.layer_spread,
            self.crown_sweep,
            self.parting_blend,
            self.parting_sweep,
        ];
        if !values.iter().all(|v| v.is_finite()) || values[1..].iter().any(|&v| v < 0.0) || self.parting_blend <= 0.0 {
            return Err(GroomError::Combing(*self));
        }
        Ok(())
    }

    /// The direction hair at `position` (head-local, on the scalp `scalp`) is combed in, with the
    /// scalp's outward `normal` there: away from the parting, back from the face, down; in the tangent
    /// plane, unit. Hair that `hangs` from the scalp turns straight down it below the upper sides.
    fn direction(&self, scalp: &Scalp, position: Vec3, normal: Vec3, hangs: bool) -> Vec3 {
        let sideways = ((position.x - scalp.centre.x - self.parting) / self.parting_blend).clamp(-1.0, 1.0);
        let facing_front = (-normal.z).clamp(0.0, 1.0);
        let crown = normal.y.max(0.0).powi(2);
        let along_parting = self.parting_sweep * (1.0 - sideways.abs()) * facing_front * facing_front;
        let back = self.sweep_back * facing_front + self.crown_sweep * crown + along_parting;
        let wanted = Vec3::new(sideways, -(1.0 - 0.7 * facing_front), back);
        // Turning straight down the skull from its upper sides to a little under its widest part (the
        // normal's up component from 0.5 to −0.25): a strand the hanging hair pulls on rests on the skull
        // only along the line that pull would slide it to, and there it holds without the style hold.
        // (Short hair, lying all the way, keeps its combed direction, which takes it back from the face
        // and the temples rather than down under the skull.)
        let below = if hangs { ((0.5 - normal.y) / 0.75).clamp(0.0, 1.0) } else { 0.0 };
        let wanted = wanted.lerp(Vec3::NEG_Y, below * below * (3.0 - 2.0 * below));
        let along = wanted.reject_from_normalized(normal);
        if along.length_squared() > 1e-6 {
            along.normalize()
        } else {
            Vec3::Z.reject_from_normalized(normal).normalize()
        }
    }
}

/// A strand combed along the scalp, then falling.
struct CombedPath<'a> {
    scalp: &'a Scalp,
    /// The surface combed along, if not the scalp's ellipsoid.
    surface: Option<&'a ScalpSurface>,
    /// What the falling hair drapes over.
    obstacles: &'a GroomObstacles,
    combing: &'a Combing,
    /// Height of this strand over the skull where it lies on it, m.
    lift: f32,
}

impl CombedPath<'_> {
    /// Step of the path traced before it is cut into edges, m.
    const STEP: f32 = 0.0005;
    /// Arc length over which a falling strand turns from the scalp's direction to its style's, m.
    const TURN: f32 = 0.03;
    /// How near the skull a falling strand's point must be to be kept out of it, m (farther, the skull's
    /// nearest point says nothing of which side it is on).
    const NEAR: f32 = 0.02;
    /// How far the scalp may face down (its normal's up component) and short hair still lie on it: below,
    /// the skull turns under and the hair falls from it.
    const UNDER_THE_SKULL: f32 = -0.6;
    /// How far above an obstacle a falling strand starts bending to slide along it, m.
    const BEND: f32 = 0.015;

    /// The point of the skull's surface radially under `point` (the nearest point of the scalp mesh, if
    /// combed along one), with the outward normal there.
    fn on_skull(&self, point: Vec3) -> (Vec3, Vec3) {
        match self.surface {
            Some(surface) => surface.nearest(point),
            None => {
                let root = self.scalp.radially_under(point);
                (root.position, root.normal)
            }
        }
    }

    /// The nodes of a strand `length` m long in `segments` equal edges from `root`, and its material
    /// direction: traced along the scalp while the scalp faces up (all the way for short hair), rising
    /// from the root to `lift` over its first edge, then falling in `style`'s shape.
    fn grow(
        &self,
        root: ScalpRoot,
        style: HairStyle,
        length: f32,
        segments: usize,
        random: &mut fastrand::Rng,
    ) -> (Vec<Vec3>, Vec3) {
        let edge_length = length / segments as f32;
        let mut path = vec![root.position];
        let (mut surface, mut normal) = (root.position, root.normal);
        // Along the scalp down to its hairline, so that hair covers the skull below its widest part too;
        // short hair all the way, but not under the skull.
        let lies_everywhere = style == HairStyle::Short;
        let mut tangent = self.combing.direction(self.scalp, surface, normal, !lies_everywhere);
        let first_direction = tangent;
        let mut arc = 0.0;
        let lies_on = |normal: Vec3| {
            normal.y > 0.0 || self.scalp.grows_hair_at(normal) || (lies_everywhere && normal.y > Self::UNDER_THE_SKULL)
        };
        while arc < length && lies_on(normal) {
            let combed = self.combing.direction(self.scalp, surface, normal, !lies_everywhere);
            // Where the combing turns back on itself (its "down" under a skull), the hair leaves the scalp.
            if combed.dot(tangent) < 0.5 {
                break;
            }
            tangent = combed;
            let (next, next_normal) = self.on_skull(surface + Self::STEP * tangent);
            // At the edge of a scalp mesh the hair leaves it.
            if self.surface.is_some() && next.distance(surface) < 0.25 * Self::STEP {
                break;
            }
            (surface, normal) = (next, next_normal);
            arc += Self::STEP;
            let height = self.lift * (arc / edge_length).min(1.0);
            path.push(surface + height * normal);
        }
        // Falling, turning from the scalp's direction into the style's.
        if arc < length {
            let outward = Vec3::new(normal.x, 0.0, normal.z).normalize_or(Vec3::Z);
            let shape = StrandShape::new(style, Vec3::NEG_Y, edge_length, random).facing(outward);
            let mut point = *path.last().unwrap_or(&root.position);
            let (start, lifted) = (arc, self.lift * (arc / edge_length).min(1.0));
            // The path's own length (a curl pushed out of the skull may lie longer or shorter than its arc).
            let mut walked: f32 = path.windows(2).map(|pair| pair[0].distance(pair[1])).sum();
            // Where a strand lands on top of an obstacle, it slides off the side its root is on: front or back.
            let slide = Vec3::Z * (root.position.z - self.scalp.centre.z).signum();
            while walked < length && arc < 4.0 * length {
                let fallen = arc - start;
                let blend = (fallen / Self::TURN).min(1.0);
                let blend = blend * blend * (3.0 - 2.0 * blend);
                let mut direction = tangent.lerp(shape.tangent(fallen), blend).normalize_or(Vec3::NEG_Y);
                // Nearing an obstacle, the strand bends to slide down along it, all the way once it lies on it.
                if let Some((gap, normal)) = self.obstacles.nearest(point, self.lift, Self::BEND, root.position)
                    && direction.dot(normal) < 0.0
                {
                    let downhill = Vec3::NEG_Y.reject_from_normalized(normal);
                    let along = (downhill + 0.3 * slide.reject_from_normalized(normal)).normalize_or(downhill);
                    let closeness = (1.0 - gap / Self::BEND).clamp(0.0, 1.0);
                    direction = direction.lerp(along, closeness * closeness).normalize_or(along);
                }
                point += Self::STEP * direction;
                arc += Self::STEP;
                // A strand that falls from its root still rises to its lift over the first edge.
                let rise = self.lift * (arc / edge_length).min(1.0) - lifted;
                // Curls and waves swing round the line they fall along: none of that into the skull.
                let mut placed = point + rise * normal;
                let skull = match self.surface {
                    Some(surface) => surface.nearest_near(placed),
                    None => Some(self.on_skull(placed)),
                };
                if let Some((under, outward)) = skull
                    && (placed - under).dot(outward) < self.lift
                    && placed.distance(under) < Self::NEAR
                {
                    let height = (placed - under).dot(outward);
                    // Pushed out, and falling on from there.
                    let push = (self.lift - height) * outward;
                    placed += push;
                    point += push;
                }
                if let Some((gap, normal)) = self.obstacles.nearest(placed, self.lift, 0.0, root.position) {
                    // Inside: out onto the surface, a lift above the obstacle.
                    let out = -gap * normal;
                    (placed, point) = (placed + out, point + out);
                }
                walked += path.last().map_or(0.0, |last| last.distance(placed));
                path.push(placed);
            }
        }
        let nodes = resample(&path, edge_length, segments);
        let material_direction =
            root.normal.cross(nodes[1] - nodes[0]).normalize_or(root.normal.cross(first_direction));
        (nodes, material_direction)
    }
}

/// The solution of the symmetric positive definite system `matrix · x = right` (Cholesky), if the matrix is
/// positive definite.
fn solve_symmetric(mut matrix: [[f64; 6]; 6], right: [f64; 6]) -> Option<[f64; 6]> {
    let scale = (0..6).map(|i| matrix[i][i]).fold(0.0, f64::max);
    for j in 0..6 {
        let pivot = matrix[j][j] - (0..j).map(|k| matrix[j][k] * matrix[j][k]).sum::<f64>();
        if pivot.is_nan() || pivot <= 1e-14 * scale {
            return None;
        }
        matrix[j][j] = pivot.sqrt();
        for i in j + 1..6 {
            matrix[i][j] = (matrix[i][j] - (0..j).map(|k| matrix[i][k] * matrix[j][k]).sum::<f64>()) / matrix[j][j];
        }
    }
    let mut x = right;
    for i in 0..6 {
        x[i] = (x[i] - (0..i).map(|k| matrix[i][k] * x[k]).sum::<f64>()) / matrix[i][i];
    }
    for i in (0..6).rev() {
        x[i] = (x[i] - (i + 1..6).map(|k| matrix[k][i] * x[k]).sum::<f64>()) / matrix[i][i];
    }
    Some(x)
}

/// `segments + 1` points at arc lengths `0, edge, 2 edge, …` along the polyline `path`, continued along
/// its last direction where the path ends short.
fn resample(path: &[Vec3], edge: f32, segments: usize) -> Vec<Vec3> {
    let mut nodes = Vec::with_capacity(segments + 1);
    let (mut walked, mut index) = (0.0, 0);
    for node in 0..=segments {
        let wanted = edge * node as f32;
        while index + 1 < path.len() && walked + path[index].distance(path[index + 1]) < wanted {
            walked += path[index].distance(path[index + 1]);
            index += 1;
        }
        let point = match path.get(index + 1) {
            Some(&next) => {
                let span = path[index].distance(next).max(f32::MIN_POSITIVE);
                path[index].lerp(next, ((wanted - walked) / span).clamp(0.0, 1.0))
            }
            // Past the path's end (a path cut short, by an obstacle or the combing's turn), on along its
            // last direction: every edge keeps its length (a strand with nodes on top of each other
            // cannot be simulated).
            None => {
                let last = path[index];
                let direction = path[..index]
                    .iter()
                    .rev()
                    .map(|&before| (last - before).normalize_or_zero())
                    .find(|direction| *direction != Vec3::ZERO)
                    .unwrap_or(Vec3::NEG_Y);
                last + direction * (wanted - walked).max(0.0)
            }
        };
        nodes.push(point);
    }
    nodes
}

/// The rest shape of one strand: its edges, built from a tangent that turns with arc length.
struct StrandShape {
    style: HairStyle,
    normal: Vec3,
    down_the_scalp: Vec3,
    across: Vec3,
    edge_length: f32,
    curl_radius: f32,
    curl_phase: f32,
}

impl StrandShape {
    /// Wavelength of [`HairStyle::Wavy`], m.
    const WAVELENGTH: f32 = 0.06;
    /// Largest angle of a wave's tangent from the root direction, rad.
    const WAVE_ANGLE: f32 = 0.5;
    /// Radius of [`HairStyle::Curly`]'s curls, m.
    const CURL_RADIUS: f32 = 0.006;
    /// Angle of a curl's fibre from the curl's axis, rad (its pitch is `2πR / tan` of it).
    const CURL_ANGLE: f32 = FRAC_PI_3;
    /// Arc length over which a curl opens up from the straight root, m.
    const CURL_ONSET: f32 = 0.01;

    fn new(style: HairStyle, normal: Vec3, edge_length: f32, random: &mut fastrand::Rng) -> Self {
        let down = Vec3::NEG_Y.reject_from_normalized(normal);
        let down_the_scalp = if down.length_squared() > 1e-6 { down.normalize() } else { Vec3::Z };
        Self {
            style,
            normal,
            down_the_scalp,
            across: normal.cross(down_the_scalp),
            edge_length,
            curl_radius: Self::CURL_RADIUS.max(edge_length) * (0.85 + 0.3 * random.f32()),
            curl_phase: TAU * random.f32(),
        }
    }

    /// The same shape with its waves and curls turned to start towards `outward` (perpendicular to its
    /// growing direction).
    fn facing(mut self, outward: Vec3) -> Self {
        self.down_the_scalp = outward;
        self.across = self.normal.cross(outward);
        self
    }

    /// Edge `index`, m: `edge_length` along the tangent at its start, so the root edge lies along the normal.
    fn edge(&self, index: usize) -> Vec3 {
        self.edge_length * self.tangent(self.edge_length * index as f32)
    }

    /// The unit tangent `arc` m along the strand.
    fn tangent(&self, arc: f32) -> Vec3 {
        match self.style {
            HairStyle::Straight | HairStyle::Short | HairStyle::Long => self.normal,
            HairStyle::Wavy => {
                let angle = Self::WAVE_ANGLE * (TAU * arc / Self::WAVELENGTH).sin();
                angle.cos() * self.normal + angle.sin() * self.down_the_scalp
            }
            HairStyle::Curly => {
                let onset = (arc / Self::CURL_ONSET).min(1.0);
                let angle = Self::CURL_ANGLE * onset * onset * (3.0 - 2.0 * onset);
                let around = self.curl_phase + Self::CURL_ANGLE.sin() * arc / self.curl_radius;
                let sideways = around.cos() * self.down_the_scalp + around.sin() * self.across;
                angle.cos() * self.normal + angle.sin() * sideways
            }
        }
    }
}

/// Why a [`HairGroom`] could not grow hair.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GroomError {
    /// Strands need at least two edges.
    #[error("a groomed strand needs at least 2 segments (edges), got {0}")]
    TooFewSegments(usize),
    /// More edges per strand than [`MAX_GROOM_SEGMENTS`].
    #[error("a groomed strand has at most {MAX_GROOM_SEGMENTS} segments (edges), got {0}")]
    TooManySegments(usize),
    /// More hairs (strands and their followers) than [`MAX_GROOM_HAIRS`].
    #[error(
        "a groom grows at most {MAX_GROOM_HAIRS} hairs, got {strand_count} strands with {followers_per_guide} followers each"
    )]
    TooManyHairs {
        /// The strands asked for.
        strand_count: usize,
        /// The followers per strand asked for.
        followers_per_guide: usize,
    },
    /// A [`GroomPlacement`](crate::groom::GroomPlacement) value out of its range.
    #[error("the groom placement's {what} is {value}, {requirement}")]
    InvalidPlacement {
        /// Which value.
        what: &'static str,
        /// The value given.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// No skull ellipsoid fits a head's points ([`Scalp::fitted_to`]).
    #[error("no skull ellipsoid fits the head's {points} points: {reason}")]
    ScalpFit {
        /// How many points were given.
        points: usize,
        /// Why none fits.
        reason: &'static str,
    },
    /// A head's [`HeadAxes`](super::HeadAxes) do not make a frame.
    #[error(
        "the head's axes need a forward and an up that are finite, not zero and not parallel, got forward {forward} and up {up}"
    )]
    HeadAxes {
        /// The forward given.
        forward: Vec3,
        /// The up given.
        up: Vec3,
    },
    /// The skull ellipsoid is degenerate.
    #[error(
        "the scalp's skull needs a finite centre and positive finite semi-axes, got centre {centre} and semi-axes {semi_axes}"
    )]
    Skull {
        /// The centre given, m.
        centre: Vec3,
        /// The semi-axes given, m.
        semi_axes: Vec3,
    },
    /// A hairline height outside −1 to 1.
    #[error("the scalp's {name} height must lie between -1 and 1, got {height}")]
    Hairline {
        /// Which hairline.
        name: &'static str,
        /// The height given.
        height: f32,
    },
    /// The gravity preload is outside 0 to 1.
    #[error("the groom's gravity preload must lie between 0 and 1, got {0}")]
    GravityPreload(f32),
    /// The follower clumping is outside 0 to 1.
    #[error("the groom's follower clumping must lie between 0 and 1, got {0}")]
    FollowerClumping(f32),
    /// The follower clumping's variation is outside 0 to 1.
    #[error("the groom's follower clumping variation must lie between 0 and 1, got {0}")]
    FollowerClumpingVariation(f32),
    /// The follower scatter is negative or not finite.
    #[error("the groom's follower scatter must be a length of 0 m or more, got {0}")]
    FollowerScatter(f32),
    /// The hairline's fade is negative or not finite.
    #[error("the groom's hairline fade must be a width of 0 m or more, got {0}")]
    HairlineFade(f32),
    /// A combing parameter is negative or not finite, or the parting's blend is not positive.
    #[error(
        "the groom's combing needs finite values, with sweep_back, lift, layer_spread, crown_sweep and parting_sweep not \
         negative and parting_blend positive: {0:?}"
    )]
    Combing(Combing),
    /// A scalp mesh has no triangle with an area (and some hair density).
    #[error("the scalp mesh has no triangle with an area and hair to grow")]
    NoScalpTriangles,
    /// A scalp mesh's data cannot be read.
    #[error("the scalp mesh cannot be read: {0}")]
    ScalpMesh(MeshColliderError),
    /// A scalp mesh's hair density has a count other than its vertices'.
    #[error("the scalp mesh has {vertices} vertices but {densities} hair densities")]
    ScalpDensity {
        /// The mesh's vertices.
        vertices: usize,
        /// The densities given.
        densities: usize,
    },
    /// A scalp mesh's hair density outside 0 to 1.
    #[error("the hair density of scalp vertex {vertex} must lie between 0 and 1, got {value}")]
    ScalpDensityValue {
        /// The vertex.
        vertex: usize,
        /// Its density.
        value: f32,
    },
    /// The hairline leaves less than 0.1 % of the skull to grow hair on.
    #[error("the scalp's hairline (nape height {nape_height}, brow height {brow_height}) leaves no room for hair")]
    EmptyScalp {
        /// The nape height given.
        nape_height: f32,
        /// The brow height given.
        brow_height: f32,
    },
}

/// Marks a strand grown by a head's [`HairGroom`]: regrowing replaces these and keeps the head's others.
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone)]
pub struct GroomedStrand;

/// Heads whose groom or groom surface is new or changed.
type GroomHeads<'w, 's> = Query<
    'w,
    's,
    (Entity, &'static HairGroom, Option<&'static GroomSurface>, Option<&'static HeadStrands>),
    Or<(Changed<HairGroom>, Changed<GroomSurface>)>,
>;

/// Grows the hair of every head whose [`HairGroom`] is new or changed, replacing its groomed strands, draped
/// over the colliders tied to the head as they are then; a head with a [`GroomSurface`] grows on it once
/// it is known, and again when it changes.
pub(super) fn grow_groomed_hair(
    mut commands: Commands,
    heads: GroomHeads,
    groomed: Query<(), With<GroomedStrand>>,
    (colliders, shapes, transforms): (Query<&HeadColliders>, Query<&HairCollider>, TransformHelper),
) {
    for (head, groom, surface, strands) in &heads {
        if matches!(surface, Some(GroomSurface::Waiting)) {
            continue;
        }
        // Grown in metres on a scaled head (its scale taken out), then given to it.
        let frame = GroomFrame::of_head(head, &transforms);
        let obstacles = GroomObstacles::of_head(head, !frame.is_identity(), &colliders, &shapes, &transforms);
        let grown = frame.surface_of(surface).and_then(|surface| {
            let mut grown =
                groom.grow_with_followers_around(surface.as_ref().and_then(GroomSurface::surface), &obstacles)?;
            let widths = groom.hairline_widths(&grown);
            frame.grown_to_head(&mut grown);
            Ok((grown, widths))
        });
        let (grown, widths) = match grown {
            Ok(grown) => grown,
            Err(error) => {
                error!("hair groom of head {head} rejected, it keeps its hair: {error}");
                continue;
            }
        };
        for &strand in strands.map_or(&[][..], HeadStrands::strands) {
            if groomed.contains(strand) {
                commands.entity(strand).despawn();
            }
        }
        let hairs = RepresentedHairs(groom.hairs_per_strand());
        for ((strand, followers), widths) in grown.into_iter().zip(widths) {
            let mut spawned = commands.spawn((strand, followers, StrandOf(head), GroomedStrand, hairs));
            if widths.hairs.iter().any(|&share| share < 1.0) {
                spawned.insert(widths);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_skull_is_fitted_to_points_on_its_top_alone() {
        let skull = Scalp { centre: Vec3::new(0.01, 0.04, -0.07), semi_axes: Vec3::new(0.07, 0.085, 0.1), ..default() };
        // Points over the top half of the ellipsoid only, as a scalp or a head's upper vertices lie.
        let points: Vec<Vec3> = (0..400)
            .map(|index| {
                let height = index as f32 / 400.0;
                let around = index as f32 * 2.399_963;
                let ring = (1.0 - height * height).sqrt();
                skull.centre + skull.semi_axes * Vec3::new(ring * around.cos(), height, ring * around.sin())
            })
            .collect();
        let fitted = Scalp::default().fitted_to(&points).unwrap();
        assert!(fitted.centre.distance(skull.centre) < 1e-5, "{}", fitted.centre);
        assert!((fitted.semi_axes - skull.semi_axes).abs().max_element() < 1e-5, "{}", fitted.semi_axes);
        assert_eq!(
            (fitted.nape_height, fitted.brow_height),
            (Scalp::default().nape_height, Scalp::default().brow_height)
        );
        // A plane fits no ellipsoid, and too few points none at all: errors, not NaN.
        let flat: Vec<Vec3> =
            (0..20).map(|index| Vec3::new(index as f32 * 0.01, 0.0, (index % 4) as f32 * 0.01)).collect();
        assert!(matches!(Scalp::default().fitted_to(&flat), Err(GroomError::ScalpFit { .. })));
        assert!(matches!(Scalp::default().fitted_to(&points[..5]), Err(GroomError::ScalpFit { .. })));
    }

    #[test]
    fn a_path_cut_short_is_resampled_into_edges_of_one_length() {
        // A path of 2.5 edges, resampled to 6: on past its end along its last direction.
        let path = [Vec3::ZERO, Vec3::new(0.0, -0.01, 0.0), Vec3::new(0.015, -0.01, 0.0)];
        let nodes = resample(&path, 0.01, 6);
        assert_eq!(nodes.len(), 7);
        for (index, edge) in nodes.windows(2).enumerate() {
            assert!((edge[0].distance(edge[1]) - 0.01).abs() < 1e-6, "edge {index}: {:?}", edge);
        }
        assert!(nodes[6].distance(Vec3::new(0.05, -0.01, 0.0)) < 1e-6, "{}", nodes[6]);
    }
}
