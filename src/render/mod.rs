//! Hair drawn as hair: every strand of a head, guides and followers, as a strip of thin camera-facing
//! ribbons in Bevy's PBR pipeline, lit by Bevy's lights with an anisotropic hair shading model, casting and
//! receiving Bevy's shadows. The gizmo lines ([`debug`](mod@crate::debug)) stay as a debug view.
//!
//! **How a frame is drawn.** For each head, [`HairStrips`] lays its hairs out once (the guides in
//! [`crate::simulation::HeadStrands`] order, each followed by its followers) and, every frame, writes their node
//! positions, interpolated between the last two fixed steps like the gizmos, into one buffer of `f32`
//! triples, in parallel over the guides. The GPU receives that buffer (one `write_buffer` into a storage
//! buffer that lives as long as the layout) and a static mesh of two vertices per node that says which node
//! each vertex stands for, which side of the ribbon it is on and how thick the hair is there. The positions
//! are where the hair was stepped; the hair mesh's transform carries them onto the head where it is in
//! the frame ([`HeadMotion::drawn_to_now`](crate::simulation::HeadMotion::drawn_to_now)), so that hair
//! stepped before the game moved its head does not trail the scalp. The vertex shader reads the node and
//! its neighbours through that transform, and expands the ribbon across the strand, along
//! `tangent × (direction to the eye)`, by the hair's diameter; sub-pixel hairs are widened to
//! [`HairAppearance::min_pixel_width`] and their coverage lowered by the same factor
//! ([`ribbon_width`]), so thin hair fades instead of shimmering. Coverage goes to the GPU's multisampling
//! as a sample mask: each hair covers a random subset of a pixel's samples (as many as its coverage is
//! worth), drawn afresh per hair and pixel, so that hairs over one another cover independent samples and
//! add up as layers of real hair do. That needs no sorting (thousands of hairs cross in every pixel),
//! keeps depth for shadows, and comes with the 4× MSAA Bevy's cameras have by default; alpha to
//! coverage's fixed pattern per alpha level would stack every hair on the same samples, and
//! order-independent transparency would cost a list of fragments per pixel. Without multisampling, the
//! same draw keeps or drops whole pixels. The draw changes with the view's sub-pixel jitter (Bevy's
//! `TemporalJitter`, which temporal anti-aliasing moves through eight offsets, one a frame), so that under
//! TAA (MSAA off) each frame covers other pixels and TAA's history averages the dither into the hair's
//! coverage; without jitter the same pixels are drawn every frame, and the hair does not shimmer.
//!
//! **Motion vectors.** While a camera draws motion vectors, each head also keeps the positions it drew
//! the frame before, in a second buffer of the same layout ([`HairMesh::previous_positions_buffer`]): at
//! the start of every frame the GPU copies the drawn buffer into it, before anything writes this frame's
//! positions, whether the CPU uploads them or the GPU places the followers. A camera with Bevy's
//! `MotionVectorPrepass` (which `MotionBlur` and temporal anti-aliasing ask for) then draws each ribbon
//! vertex from its node there, under the mesh's transform of the frame before, so that moving hair blurs
//! along its own motion and TAA follows it instead of smearing it. A head drawn for the first time, or
//! first seen by such a camera, has no frame before: it starts still (its frame before is made what it
//! draws in that frame, once written, whether the CPU or the GPU placed it). The hair's
//! prepasses cover the same samples as its main pass, so a camera's depth prepass does not hide the hair
//! behind a hair's uncovered samples.
//!
//! **Shading** (`draw.wgsl`): Kajiya and Kay's hair model (SIGGRAPH 1989), diffuse `∝ sin(t, l)` and
//! specular `∝ sin(t, h)^p`, with Scheuermann's two shifted highlights ("Hair Rendering and Shading",
//! GDC 2004): the primary, white, reflected at the cuticle and shifted towards the root; the secondary,
//! tinted by the hair's colour, through the fibre and back, shifted towards the tip and broader. Shifts and
//! widths follow Marschner et al. (SIGGRAPH 2003): the cuticle scales tilt by `α` ≈ 2–4°, the reflection
//! `R` shifts by `−2α`, the `TRT` lobe by `+3α`, and `TRT` is twice as wide as `R`. Colours can come from
//! melanin ([`HairAppearance::from_melanin`]). Directional lights reach into the hair as through real
//! hair, dimmed `exp(−d / penetration)` by the depth `d` of hair in front in the light's shadow map
//! (TressFX's deep shadows; [`HairAppearance::light_penetration`]). Each highlight is widened by the
//! turn of the hair's direction within the pixel, keeping the light it reflects, so that a hair thinner
//! than a pixel does not glint as a white speck ([`HairAppearance::highlight_filtering`]).
//!
//! The CPU side ([`HairStrips`], [`ribbon_width`], [`HairAppearance`]) needs no renderer; the plugin that
//! draws ([`HairRenderPlugin`]) needs the crate's `render` feature.

use std::ops::Range;

use bevy::math::{Vec3, Vec4};
use bevy::prelude::*;

use crate::followers::FollowerNodes;
use crate::groom::{StrandColors, StrandWidths};
use crate::simulation::{SimulatedStrand, StrandNodes};
use crate::volume::RepresentedHairs;

#[cfg(feature = "render")]
mod draw;
// What the GPU is sent for followers and drawing: public for the crate's benchmark, not an API.
#[doc(hidden)]
pub mod feed;
#[cfg(feature = "render")]
mod followers;
#[cfg(feature = "gpu")]
mod gpu_step;
#[cfg(feature = "render")]
pub use draw::{DrawnStrand, HairMaterial, HairMesh, HairRenderPlugin, HairShading};
#[cfg(feature = "gpu")]
pub use gpu_step::{GpuReadBackRate, HairGpuPlugin, HairGpuSettings, HairGpuStatus};

/// How a head's hair looks when drawn by the [`HairRenderPlugin`]. Put it on the [`crate::simulation::HairHead`]
/// entity; without one, hair is drawn with [`HairAppearance::default`]. Changes apply the next frame.
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct HairAppearance {
    /// Colour of the hair at the root (the fibre's own colour, as lit diffusely).
    pub root_color: Color,
    /// Colour at the tip; the colour blends from root to tip along each hair.
    pub tip_color: Color,
    /// How much each hair's shade varies from its neighbours', 0 to 1: a hair's colour is scaled by a
    /// factor drawn uniformly from `1 ± color_variation / 2`, and its turn from root to tip colour moves
    /// by as much of its length. Hair is never one flat colour.
    pub color_variation: f32,
    /// Strength of the highlights, 0 to 1: the fraction of light the cuticle reflects in the primary
    /// highlight at its peak (about 0.05–0.1 for real hair, higher reads as oiled or wet).
    pub specular: f32,
    /// Tilt `α` of the cuticle scales, rad (Marschner et al. 2003: 2–4° in real hair). The primary
    /// highlight shifts by `2α` towards the root, the secondary by `3α` towards the tip.
    pub cuticle_tilt: f32,
    /// Angular width `β` of the primary highlight, rad (Marschner et al.: 5–10°); the secondary is twice
    /// as wide.
    pub highlight_width: f32,
    /// How much each highlight widens where the hair's tangent turns within a pixel, 0 to 4.
    ///
    /// The lobe's angular width `β` becomes `β' = √(β² + f σ²)` (`σ`, rad, the turn over one pixel from
    /// the screen-space derivatives: across a hair thinner than a pixel the tangent the highlight sees
    /// turns with the fibre's side) and its peak falls by `β/β'`, so the light it reflects stays the same
    /// (Toksvig's filtering, "Mipmapping normal maps", 2005, applied to the fibre's lobe). Without it
    /// (0) a hair drawn a pixel wide reflects the whole narrow peak where it happens to face the light:
    /// white speckles that move with the hair. Default 1.
    pub highlight_filtering: f32,
    /// Drawn thickness of each hair as a multiple of the thickness that covers what the real hair covers:
    /// the strand material's diameter `2 √(a₁ a₂)` (0.08 mm for real hair) times the hairs each drawn hair
    /// stands for (a guide's [`crate::volume::RepresentedHairs`] shared by it and its followers: a groom of
    /// 2 000 guides with 10 followers each standing for 100 000 hairs draws each 4.5 hairs wide). 1 by
    /// default.
    pub thickness_scale: f32,
    /// How much hairs thin towards the tip, 0 to 1: the tip is `1 − tip_taper` of the root's thickness.
    pub tip_taper: f32,
    /// How much the drawn hairs' lengths vary, 0 to 1: each drawn hair ends short of its strand's tip by
    /// a fraction of its length drawn (per hair, the same every frame) uniformly from 0 to
    /// `length_variation`, in whole edges, and tapers to its own end. The ends of a lock are then feathered
    /// instead of cut straight; the simulated strands keep their lengths. Default 0.15.
    pub length_variation: f32,
    /// Narrowest a hair is drawn, in pixels (of the view, or of a shadow map's texels). A hair thinner than
    /// this on screen is drawn this wide with its coverage lowered in proportion ([`ribbon_width`]).
    pub min_pixel_width: f32,
    /// Darkening of the ambient light at the roots, 0 to 1: ambient light on a hair is scaled from
    /// `1 − root_occlusion` at the root to 1 at the tip, a cheap stand-in for the light the hair above
    /// takes (the shadow maps handle direct light).
    pub root_occlusion: f32,
    /// How deep a directional light's light gets into the hair, m: behind a depth `d` of hair (measured in
    /// the light's shadow map from the nearest hair or head in front) a hair gets `exp(−d / light_penetration)`
    /// of it, as light through real hair dims layer after layer (TressFX's deep shadows). 0 keeps the
    /// shadow map's hard shadow, which (offset towards the light by its depth bias, 2 cm by Bevy's
    /// default) leaves the hair behind a little hair fully lit and the hair behind more fully dark. Point
    /// and spot lights always cast hard shadows. Default 4 mm.
    pub light_penetration: f32,
}

impl Default for HairAppearance {
    /// Brown hair ([`HairAppearance::from_melanin`] with 1.3 eumelanin and 0.2 pheomelanin), 20 % brightness
    /// variation, real thickness tapered by half, 1-pixel minimum width.
    fn default() -> Self {
        Self::from_melanin(1.3, 0.2)
    }
}

impl HairAppearance {
    /// Hair coloured by its pigments, with the other fields at their defaults: concentrations of eumelanin
    /// (dark brown to black, 0 to about 8) and pheomelanin (red, 0 to about 2) in the units of d'Eon et al.
    /// (EGSR 2011), whose absorption coefficients per unit fibre radius are `(0.419, 0.697, 1.37)` and
    /// `(0.187, 0.4, 1.05)` (linear red, green, blue). The absorption `σ` is turned into the colour the hair
    /// shows by inverting Chiang et al.'s fit (EGSR 2016, eq. 9) at a roughness `β = 0.3`:
    /// `c = exp(−5.89 √σ)`. The tips are a little lighter (sun-bleached), `c^0.8`.
    pub fn from_melanin(eumelanin: f32, pheomelanin: f32) -> Self {
        let absorption =
            eumelanin.max(0.0) * Vec3::new(0.419, 0.697, 1.37) + pheomelanin.max(0.0) * Vec3::new(0.187, 0.4, 1.05);
        let color = Vec3::new(
            (-5.89 * absorption.x.sqrt()).exp(),
            (-5.89 * absorption.y.sqrt()).exp(),
            (-5.89 * absorption.z.sqrt()).exp(),
        );
        let tip = color.powf(0.8);
        Self {
            root_color: Color::linear_rgb(color.x, color.y, color.z),
            tip_color: Color::linear_rgb(tip.x, tip.y, tip.z),
            ..Self::DEFAULT_SHADING
        }
    }

    /// The default shading parameters, colours aside (for [`HairAppearance::from_melanin`]).
    const DEFAULT_SHADING: Self = Self {
        root_color: Color::BLACK,
        tip_color: Color::BLACK,
        color_variation: 0.2,
        specular: 0.05,
        cuticle_tilt: 3.0 * std::f32::consts::PI / 180.0,
        highlight_width: 7.0 * std::f32::consts::PI / 180.0,
        highlight_filtering: 1.0,
        thickness_scale: 1.0,
        tip_taper: 0.5,
        length_variation: 0.15,
        min_pixel_width: 1.0,
        root_occlusion: 0.6,
        light_penetration: 0.004,
    };

    /// Natural hair colours by melanin, for menus: black, dark brown, brown, auburn, red, blonde, light
    /// blonde, white (no pigment).
    pub fn presets() -> [(&'static str, Self); 8] {
        [
            ("black", Self::from_melanin(8.0, 0.0)),
            ("dark brown", Self::from_melanin(3.0, 0.2)),
            ("brown", Self::from_melanin(1.3, 0.2)),
            ("auburn", Self::from_melanin(0.9, 1.0)),
            ("red", Self::from_melanin(0.25, 1.2)),
            ("blonde", Self::from_melanin(0.3, 0.1)),
            ("light blonde", Self::from_melanin(0.12, 0.05)),
            ("white", Self::from_melanin(0.0, 0.0)),
        ]
    }

    /// Why the appearance cannot be drawn, naming the field, if it cannot.
    pub fn validate(&self) -> Result<(), String> {
        let fields = [
            ("color_variation", self.color_variation, 0.0, 1.0),
            ("specular", self.specular, 0.0, 1.0),
            ("cuticle_tilt", self.cuticle_tilt, -0.5, 0.5),
            ("highlight_width", self.highlight_width, 1e-3, 1.5),
            ("highlight_filtering", self.highlight_filtering, 0.0, 4.0),
            ("thickness_scale", self.thickness_scale, 1e-3, 1e3),
            ("tip_taper", self.tip_taper, 0.0, 1.0),
            ("length_variation", self.length_variation, 0.0, 1.0),
            ("min_pixel_width", self.min_pixel_width, 0.0, 16.0),
            ("root_occlusion", self.root_occlusion, 0.0, 1.0),
            ("light_penetration", self.light_penetration, 0.0, 1.0),
        ];
        for (name, value, low, high) in fields {
            if !(low..=high).contains(&value) {
                return Err(format!("{name} = {value} is not within {low} … {high}"));
            }
        }
        Ok(())
    }
}

/// A well-mixed hash of `value` to 0 … 1 (PCG, Jarzynski and Olano 2020), for per-hair variation that
/// stays the same from frame to frame.
fn hash01(value: u32) -> f32 {
    let state = value.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    ((word >> 22) ^ word) as f32 / u32::MAX as f32
}

/// How wide a ribbon is drawn and how much of it is covered: a hair of `diameter` (m) where one pixel
/// spans `pixel` (m) is drawn `max(diameter, min_pixels · pixel)` wide with coverage
/// `diameter / width`, so that its drawn area (width × coverage) is its true one. The vertex shader
/// computes the same.
pub fn ribbon_width(diameter: f32, pixel: f32, min_pixels: f32) -> (f32, f32) {
    let width = diameter.max(min_pixels * pixel);
    if width > 0.0 { (width, diameter / width) } else { (0.0, 0.0) }
}

impl GuideLayout {
    /// The layout of the guide `entity` as the renderer draws it: the radius its material's (the geometric
    /// mean of its semi-axes), widened so that the hair drawn covers what the real hair would: a guide
    /// standing for `represented` hairs ([`RepresentedHairs`]) draws itself and its followers, each
    /// `represented / (1 + followers)` times as wide as one hair (at least 1).
    pub fn drawn(
        entity: Entity,
        strand: &SimulatedStrand,
        nodes: &StrandNodes,
        followers: Option<&FollowerNodes>,
        represented: Option<&RepresentedHairs>,
    ) -> Self {
        let material = strand.rod().material();
        let radius = (material.semi_axis_1 * material.semi_axis_2).sqrt() as f32;
        let mut guide = Self::new(entity, nodes, followers, radius);
        guide.radius *= represented.map_or(1.0, |hairs| (hairs.0 as f32 / (1 + guide.followers) as f32).max(1.0));
        guide
    }

    /// The layout of the guide `entity` with these `nodes` and `followers`, drawn with `radius` (m).
    pub fn new(entity: Entity, nodes: &StrandNodes, followers: Option<&FollowerNodes>, radius: f32) -> Self {
        Self {
            entity,
            nodes: nodes.positions.len() as u32,
            followers: followers.map_or(0, |followers| followers.count() as u32),
            binding: followers.map_or(0, FollowerNodes::binding),
            radius,
        }
    }
}

/// One drawn hair's nodes in its head's node buffer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrawnHair {
    /// Index of its root node in the buffer.
    pub first_node: u32,
    /// Number of nodes, root first.
    pub nodes: u32,
    /// Radius of the hair at its root, m (drawn times [`HairAppearance::thickness_scale`]).
    pub radius: f32,
}

/// One guide as the layout saw it: its entity, nodes, followers (and which binding of them) and radius (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuideLayout {
    /// The guide strand's entity.
    pub entity: Entity,
    /// Nodes of the guide (and of each of its followers).
    pub nodes: u32,
    /// Followers the guide carries.
    pub followers: u32,
    /// Which binding of the followers their rest offsets come from ([`FollowerNodes::binding`], 0 without
    /// followers): followers bound again are laid out again, so that the GPU takes their new offsets.
    pub binding: u64,
    /// The guide's radius, m.
    pub radius: f32,
}

/// One head's hair laid out for drawing, and its node positions for this frame (see the
/// [module documentation](self)): each guide, then its followers, each hair's nodes root first.
#[derive(Debug, Clone, Default)]
pub struct HairStrips {
    guides: Vec<GuideLayout>,
    /// First node of each guide's block (guide and followers), and one past the last node.
    guide_offsets: Vec<usize>,
    hairs: Vec<DrawnHair>,
    /// Node positions this frame, world space, m: `x y z` per node, flat.
    positions: Vec<f32>,
    /// Bounds of each piece's positions from the last fill (reused).
    piece_bounds: Vec<(Vec3, Vec3)>,
}

/// How many pieces the guides are cut into per thread ([`piece_ranges`]), to even out the load.
const PIECES_PER_THREAD: usize = 4;

/// The guides `0..guides` cut into runs of consecutive guides, [`PIECES_PER_THREAD`] runs per thread of
/// `threads` (at most one per guide; none without guides), for [`HairStrips::fill`] and
/// [`feed::GuideUpload::pack`] to work on in parallel.
pub(crate) fn piece_ranges(guides: usize, threads: usize) -> impl ExactSizeIterator<Item = Range<usize>> {
    let pieces = (threads.max(1) * PIECES_PER_THREAD).min(guides).max(1);
    let per_piece = guides.div_ceil(pieces).max(1);
    (0..guides.div_ceil(per_piece)).map(move |piece| piece * per_piece..((piece + 1) * per_piece).min(guides))
}

/// The first `count` items of `slice`, which keeps the rest: how each piece takes its part of an output.
pub(crate) fn take_front<'a, T>(slice: &mut &'a mut [T], count: usize) -> &'a mut [T] {
    let (front, rest) = std::mem::take(slice).split_at_mut(count);
    *slice = rest;
    front
}

impl HairStrips {
    /// Lays out `guides` (in drawing order) if they differ from the current layout; says whether they did,
    /// in which case the GPU's mesh and buffer must be rebuilt.
    pub fn set_layout(&mut self, guides: impl IntoIterator<Item = GuideLayout>) -> bool {
        let mut same = true;
        let mut count = 0;
        for guide in guides {
            if self.guides.get(count) != Some(&guide) {
                if same {
                    self.guides.truncate(count);
                    same = false;
                }
                self.guides.push(guide);
            }
            count += 1;
        }
        if count != self.guides.len() {
            self.guides.truncate(count);
            same = false;
        }
        if same {
            return false;
        }
        self.guide_offsets.clear();
        self.hairs.clear();
        let mut node = 0;
        for guide in &self.guides {
            self.guide_offsets.push(node);
            for _ in 0..=guide.followers {
                self.hairs.push(DrawnHair { first_node: node as u32, nodes: guide.nodes, radius: guide.radius });
                node += guide.nodes as usize;
            }
        }
        self.guide_offsets.push(node);
        self.positions.clear();
        self.positions.resize(3 * node, 0.0);
        true
    }

    /// The guides as laid out.
    pub fn guides(&self) -> &[GuideLayout] {
        &self.guides
    }

    /// Every drawn hair, guides and followers, in buffer order.
    pub fn hairs(&self) -> &[DrawnHair] {
        &self.hairs
    }

    /// Number of nodes in the buffer.
    pub fn node_count(&self) -> usize {
        self.positions.len() / 3
    }

    /// The node positions of the last [`HairStrips::fill`], `x y z` per node, m.
    pub fn positions(&self) -> &[f32] {
        &self.positions
    }

    /// The positions buffer itself, to hand over to the GPU without copying (swap it with one of the same
    /// length).
    pub fn positions_mut(&mut self) -> &mut Vec<f32> {
        &mut self.positions
    }

    /// The template mesh's vertices: two per node (the ribbon's two sides), each `[node, hair, packed,
    /// radius bits]`, with `packed = side | index along the hair << 1 | last << 16` and the radius (m,
    /// tapered linearly to `1 − tip_taper` of the root's at the hair's last drawn node, times
    /// `thickness_scale`) as `f32` bits. Each hair is drawn to its node `last`: its own last node, less
    /// the edges `length_variation` ([`HairAppearance::length_variation`]) takes off it (at least one
    /// edge stays); its nodes beyond are drawn as its last one, with no width. Each hair's radius is
    /// its share of its guide's ([`StrandWidths`], from `widths` by the guide's entity; whole without one,
    /// clamped to 0 to 1, whole if not finite): a share of 0 draws it with no width. Hairs longer than
    /// 32 767 nodes are cut there.
    pub fn vertices<'a>(
        &self,
        (thickness_scale, tip_taper, length_variation): (f32, f32, f32),
        widths: impl Fn(Entity) -> Option<&'a StrandWidths>,
    ) -> Vec<[u32; 4]> {
        let mut vertices = Vec::with_capacity(2 * self.node_count());
        let shares = self.guides.iter().flat_map(|guide| {
            let given = widths(guide.entity);
            (0..=guide.followers as usize).map(move |hair| {
                let share = given.and_then(|given| given.hairs.get(hair)).copied().unwrap_or(1.0);
                if share.is_finite() { share.clamp(0.0, 1.0) } else { 1.0 }
            })
        });
        for ((index, hair), share) in self.hairs.iter().enumerate().zip(shares) {
            let edges = hair.nodes.saturating_sub(1).min(0x7fff);
            let shorter =
                (hash01(index as u32 ^ 0x2c1b_3c6d) * length_variation.clamp(0.0, 1.0) * edges as f32).round() as u32;
            let last = edges.saturating_sub(shorter).max(edges.min(1));
            for along in 0..hair.nodes {
                let k = along.min(last);
                let s = if last > 0 { k as f32 / last as f32 } else { 0.0 };
                let radius =
                    if along > last { 0.0 } else { hair.radius * share * thickness_scale * (1.0 - tip_taper * s) };
                for side in 0..2 {
                    vertices.push([hair.first_node + k, index as u32, side | k << 1 | last << 16, radius.to_bits()]);
                }
            }
        }
        vertices
    }

    /// The template mesh's colours, one per vertex as [`HairStrips::vertices`] lays them out: the
    /// colour `colors` gives a guide's hairs ([`StrandColors`]) at each node, as sRGB bytes
    /// `r | g << 8 | b << 16 | 255 << 24`, or 0 for a hair it gives none for (drawn in the appearance's
    /// colours).
    pub fn colors<'a>(&self, colors: impl Fn(Entity) -> Option<&'a StrandColors>) -> Vec<u32> {
        let mut packed = Vec::with_capacity(2 * self.node_count());
        for guide in &self.guides {
            let given = colors(guide.entity);
            for hair in 0..=guide.followers as usize {
                let own = given.and_then(|given| given.hairs.get(hair)).filter(|own| own.len() == guide.nodes as usize);
                match own {
                    Some(own) => packed.extend(own.iter().flat_map(|&color| {
                        let [r, g, b, _] = Srgba::from(color).to_u8_array();
                        let word = u32::from_le_bytes([r, g, b, 255]);
                        [word, word]
                    })),
                    None => packed.extend(std::iter::repeat_n(0, 2 * guide.nodes as usize)),
                }
            }
        }
        packed
    }

    /// The template mesh's triangles: two per segment, `(2k, 2k+1, 2k+2)` and `(2k+1, 2k+3, 2k+2)` for the
    /// segment from node `k` to `k + 1` of a hair.
    pub fn indices(&self) -> Vec<u32> {
        let mut indices = Vec::with_capacity(6 * self.node_count());
        for hair in &self.hairs {
            for segment in 0..hair.nodes.saturating_sub(1) {
                let base = 2 * (hair.first_node + segment);
                indices.extend_from_slice(&[base, base + 1, base + 2, base + 1, base + 3, base + 2]);
            }
        }
        indices
    }

    /// Writes every hair's node positions a fraction `alpha` (0 to 1) of the way from the step before to the
    /// last, in parallel over pieces of the guides on up to `threads` threads, and returns their bounds
    /// (`None` when there is nothing to draw). `lookup` gives a guide's nodes and followers; a guide it does
    /// not find, or whose counts no longer match the layout, keeps its last positions (call
    /// [`HairStrips::set_layout`] first to follow changes).
    pub fn fill<'a>(
        &mut self,
        alpha: f32,
        threads: usize,
        lookup: impl Fn(Entity) -> Option<(&'a StrandNodes, Option<&'a FollowerNodes>)> + Sync,
    ) -> Option<(Vec3, Vec3)> {
        let empty = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let (guides, offsets) = (&self.guides, &self.guide_offsets);
        let ranges = piece_ranges(guides.len(), threads);
        self.piece_bounds.clear();
        self.piece_bounds.resize(ranges.len(), empty);
        let (mut positions, mut bounds): (&mut [f32], _) = (&mut self.positions, &mut self.piece_bounds[..]);
        let work = ranges.map(|range| {
            let nodes = offsets[range.end] - offsets[range.start];
            (range, take_front(&mut positions, 3 * nodes), &mut take_front(&mut bounds, 1)[0])
        });
        let lookup = &lookup;
        crate::parallel::run_in_parallel(threads, work, |(range, positions, bounds)| {
            let base = offsets[range.start];
            for guide_index in range {
                let guide = guides[guide_index];
                let start = 3 * (offsets[guide_index] - base);
                let block = &mut positions[start..3 * (offsets[guide_index + 1] - base)];
                let Some((nodes, followers)) = lookup(guide.entity) else { continue };
                let per = guide.nodes as usize;
                if nodes.positions.len() != per {
                    continue;
                }
                let (guide_block, follower_block) = block.split_at_mut(3 * per);
                write_interpolated(guide_block, &nodes.previous_positions, &nodes.positions, alpha, bounds);
                let followers =
                    followers.filter(|f| f.count() == guide.followers as usize && f.nodes_per_follower() == per);
                if let Some(followers) = followers {
                    let (previous, current) = (&followers.previous_positions, &followers.positions);
                    write_interpolated(follower_block, previous, current, alpha, bounds);
                }
            }
        });
        let (low, high) = self.piece_bounds.iter().fold(empty, |(low, high), (a, b)| (low.min(*a), high.max(*b)));
        (low.cmple(high).all()).then_some((low, high))
    }
}

/// Writes `previous + alpha (current − previous)` as `x y z` triples into `out` (as many as fit; the
/// current positions alone when the previous ones do not match), growing `bounds` to hold them.
fn write_interpolated(out: &mut [f32], previous: &[Vec3], current: &[Vec3], alpha: f32, bounds: &mut (Vec3, Vec3)) {
    let previous = if previous.len() == current.len() { previous } else { current };
    let nodes = current.len().min(out.len() / 3);
    let out = &mut out[..3 * nodes];
    for ((out, a), b) in out.chunks_exact_mut(3).zip(previous).zip(current) {
        let p = a.lerp(*b, alpha);
        out.copy_from_slice(&[p.x, p.y, p.z]);
    }
    // Over what was written, in vectors (a `min` and `max` per node here would wait on each other).
    let (low, high) = bounds_of(out);
    *bounds = (bounds.0.min(low), bounds.1.max(high));
}

/// The smallest and largest coordinates of the nodes in `xyz` (`x y z` per node); `(∞, −∞)` when there
/// are none, and a coordinate that is NaN is skipped. Four nodes (twelve numbers) at a time, as three
/// vectors loaded straight from `xyz`, whose lanes hold `x y z x`, `y z x y`, `z x y z`: every lane of
/// the three accumulators has one coordinate, sorted out at the end.
pub(crate) fn bounds_of(xyz: &[f32]) -> (Vec3, Vec3) {
    let (mut low, mut high) = ([Vec4::INFINITY; 3], [Vec4::NEG_INFINITY; 3]);
    let mut chunks = xyz.chunks_exact(12);
    for chunk in &mut chunks {
        for (k, part) in chunk.chunks_exact(4).enumerate() {
            // `value.min(low)`: where `value` is NaN, `minps` gives its second operand, so it is skipped.
            let value = Vec4::from_slice(part);
            (low[k], high[k]) = (value.min(low[k]), value.max(high[k]));
        }
    }
    let unscramble = |[a, b, c]: [Vec4; 3], pick: fn(f32, f32) -> f32| {
        let coordinate = |lanes: [f32; 4]| lanes.into_iter().reduce(pick).unwrap_or(lanes[0]);
        Vec3::new(coordinate([a.x, a.w, b.z, c.y]), coordinate([a.y, b.x, b.w, c.z]), coordinate([a.z, b.y, c.x, c.w]))
    };
    let (mut low, mut high) = (unscramble(low, f32::min), unscramble(high, f32::max));
    for node in chunks.remainder().chunks_exact(3) {
        let node = Vec3::from_slice(node);
        (low, high) = (node.min(low), node.max(high));
    }
    (low, high)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_cover_every_node_and_skip_nan() {
        // Every count from none to three whole chunks and a remainder, and a NaN at each place in turn.
        for count in 0..15_usize {
            let nodes: Vec<Vec3> = (0..count)
                .map(|node| {
                    let k = node as f32;
                    Vec3::new((k * 1.3).sin() + k * 0.1, (k * 0.7).cos() - 2.0, k * k * 0.01 - 0.5)
                })
                .collect();
            let low = nodes.iter().fold(Vec3::INFINITY, |low, node| low.min(*node));
            let high = nodes.iter().fold(Vec3::NEG_INFINITY, |high, node| high.max(*node));
            let xyz: Vec<f32> = nodes.iter().flat_map(|node| node.to_array()).collect();
            assert_eq!(bounds_of(&xyz), (low, high), "{count} nodes");
            for place in 0..xyz.len() {
                let mut with_nan = xyz.clone();
                with_nan[place] = f32::NAN;
                let (nan_low, nan_high) = bounds_of(&with_nan);
                let (axis, others) = (place % 3, nodes.iter().enumerate().filter(|&(node, _)| node != place / 3));
                let (low_axis, high_axis) = others
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(low, high), (_, node)| {
                        (low.min(node[axis]), high.max(node[axis]))
                    });
                assert_eq!((nan_low[axis], nan_high[axis]), (low_axis, high_axis), "{count} nodes, NaN at {place}");
                for other in (0..3).filter(|&other| other != axis) {
                    assert_eq!((nan_low[other], nan_high[other]), (low[other], high[other]), "{count}, {place}");
                }
            }
        }
    }

    #[test]
    fn pieces_cover_every_guide_once_in_order() {
        for guides in [0, 1, 2, 7, 8, 9, 100, 2000, 2001] {
            for threads in [0, 1, 2, 3, 16] {
                let ranges: Vec<_> = piece_ranges(guides, threads).collect();
                assert_eq!(ranges.len(), piece_ranges(guides, threads).len());
                assert!(ranges.len() <= (threads.max(1) * PIECES_PER_THREAD).min(guides));
                assert!(ranges.iter().all(|range| !range.is_empty()), "{guides} {threads}: {ranges:?}");
                let joined: Vec<usize> = ranges.into_iter().flatten().collect();
                assert_eq!(joined, (0..guides).collect::<Vec<_>>(), "{guides} guides, {threads} threads");
            }
        }
        let mut items = [1, 2, 3, 4, 5];
        let mut rest = &mut items[..];
        assert_eq!(take_front(&mut rest, 2), [1, 2]);
        assert_eq!(rest, [3, 4, 5]);
    }

    #[cfg(feature = "render")]
    #[test]
    fn an_appearance_out_of_range_is_refused_by_name_and_the_shader_gets_the_lobes_widths() {
        for (name, appearance) in HairAppearance::presets() {
            assert_eq!(appearance.validate(), Ok(()), "the preset {name}");
        }
        for filtering in [-0.1, 4.5, f32::NAN] {
            let appearance = HairAppearance { highlight_filtering: filtering, ..default() };
            let refused = appearance.validate().expect_err("out of 0 … 4");
            assert!(refused.starts_with("highlight_filtering = "), "{refused}");
        }
        // The lobes' squared widths, β² and (2β)², and the filtering as the shader reads them.
        let appearance = HairAppearance { highlight_width: 0.1, highlight_filtering: 2.5, ..default() };
        let shading = HairShading::from(&appearance);
        assert!((shading.highlights.z - 0.01).abs() < 1e-7 && (shading.highlights.w - 0.04).abs() < 1e-7);
        assert_eq!(shading.deep_shadows.y, 2.5);
    }
}
