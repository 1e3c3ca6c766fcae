//! Grooms: whole heads of hair. Two ways to get one:
//!
//! - **Procedural** ([`HairGroom`]): a few parameters (how many strands, how long, which [`HairStyle`],
//!   which [`Scalp`], [`Combing`]) grow a head of hair, with followers and gravity preload, anew whenever
//!   the groom changes. Its strands carry [`GroomedStrand`].
//! - **From a file** ([`HairGroomFile`]): a TressFX `.tfx` or Cem Yuksel `.hair` file, loaded as a
//!   [`GroomFile`] asset and placed on the head ([`GroomPlacement`]: scale, up axis, offset). Its strands
//!   carry [`FileStrand`].
//!
//! [`HairGroomPlugin`] (part of [`crate::HairPlugins`]) grows both in
//! [`HairPrepareSystems::Grow`], before the strands are built.
//!
//! # Combed grooms that hold their style
//! A [`HairGroom`] spreads its roots evenly over the scalp ellipsoid within a hairline, in one of five
//! styles (`Straight`, `Wavy`, `Curly`, `Short`, `Long`). By default the hair is **combed** ([`Combing`]:
//! parting, sweep back, lift, layer spread): each strand leaves its root along the scalp and lies on it,
//! combed away from a side parting, back from the face and the crown and down (straight down from the
//! skull's upper sides), to the hairline, then falls in its style's shape. With `combing: None` each
//! strand grows straight out along the scalp's normal. Over the last millimetres inside the hairline
//! ([`HairGroom::hairline_fade`], 8 mm by default) the drawn hair thins out, fewer and finer hairs, as a
//! real hairline does ([`StrandWidths`]).
//!
//! A groomed shape is not the shape hair rests in under gravity: simulated as it is, it sags.
//! [`HairStrand::gravity_preload`](crate::simulation::HairStrand::gravity_preload) (1 for groomed hair by
//! default) gives the strand, once built, rest curvatures and twists in which its groomed shape is its
//! static equilibrium under gravity, lying on its head's colliders where it touches them
//! ([`Rod::preload_for_gravity`](crate::rod::Rod::preload_for_gravity)). Gravity is baked into the rest
//! shape, not applied as a counter-force: turn the head over and the hair moves. How closely a groom
//! keeps its shape is measured in `docs/testing.md`.
//!
//! # Grooms from files
//! A [`HairGroomFile`] on a head puts the file's strands on it once the file is loaded; changing it, or the
//! file (hot reloading), regrows them, and a file that fails to load leaves the head's hair as it was (the
//! asset server logs why). Each strand is resampled into [`GroomPlacement::segments`] equal edges, and at
//! most [`GroomPlacement::max_strands`] are simulated, picked evenly; every other strand of the file
//! becomes a follower ([`crate::followers`]) of the simulated strand whose root is nearest its own, so
//! that the whole groom is drawn at the cost of its guides. Strands with fewer than 3 distinct
//! points or no length are skipped with one warning that counts them. A strand whose thickness makes a
//! fibre radius within [`FIBRE_RADIUS_RANGE`] gets the default material with that radius; others follow
//! [`HairSettings::default_material`](crate::simulation::HairSettings::default_material).
//!
//! A file's groom is preloaded against gravity like a grown one ([`GroomPlacement::gravity_preload`], 1
//! by default), and, since grooms are authored as they should look, strands that single hairs could not
//! hold in that shape are stiffened until they hold ([`GroomPlacement::stiffen_to_hold`], on by
//! default). Preloading makes any shape an equilibrium, but hair leaving the scalp upwards or sideways
//! longer than it can hold up (Greenhill's self-weight buckling length: 9.5 cm for human hair) stands
//! there only until the first disturbance, then falls; such a strand bends and twists as many times
//! stiffer as it takes to hold twice its weight upright, as gel or a clump of hairs bonded together
//! would ([`Rod::stiffening_to_hold`](crate::rod::Rod::stiffening_to_hold)); strands that hang keep
//! their material. Hair held in a shape its preloaded rest curl turns against (combed round a head it
//! does not lie on, held out by its bend at the root) turns over and falls as readily, and is stiffened
//! too; see [`Rod::stiffening_to_hold`](crate::rod::Rod::stiffening_to_hold).
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_hair_sim::prelude::*;
//!
//! fn spawn(mut commands: Commands, assets: Res<AssetServer>) {
//!     let placement = GroomPlacement { metres_per_unit: 0.01, up: UpAxis::Z, segments: 16, ..default() };
//!     let groom = HairGroomFile::new(assets.load("grooms/my_groom.hair")).with_placement(placement);
//!     commands.spawn((groom, Transform::from_xyz(0.0, 1.6, 0.0)));
//! }
//! ```
//!
//! # Grooms on a scalp mesh
//! A head with a [`HairScalpMesh`](crate::scalp::HairScalpMesh) grows its [`HairGroom`] on that mesh
//! instead of the [`Scalp`]'s ellipsoid ([`GroomSurface`], [`ScalpSurface`]): the roots are spread over
//! its triangles by area times the hair density painted in its vertex colours (white full, black none),
//! evenly (sample elimination: no clumps, no bald patches) and inside the [`Scalp`]'s hairline judged by
//! the mesh's normal; each strand leaves the mesh along its normal, or combed along it. The mesh is
//! taken as it is posed when the groom grows, and the groom waits while it loads. A groom file can be
//! fitted to the scalp instead of placed by hand ([`GroomPlacement::fit_to_scalp`]: scaled and moved
//! until its roots lie on it), and a file's colours are drawn ([`StrandColors`]).
//!
//! A groom's look in motion is measured, without a picture, by [`crate::debug::coverage`].

mod file;
mod head_frame;
mod procedural;
mod surface;

use bevy::ecs::schedule::InternedScheduleLabel;
use bevy::prelude::*;

pub use file::{
    FIBRE_RADIUS_RANGE, FileStrand, GroomFile, GroomFileError, GroomFileLoader, GroomPlacement, HairGroomFile,
    MIN_RELATIVE_STRAND_LENGTH, PlacedGroomFile, PlacedStrands, StrandColors, UpAxis,
};
pub(crate) use head_frame::GroomFrame;
pub use head_frame::HeadAxes;
pub use procedural::{
    Combing, GroomError, GroomObstacles, GroomedStrand, HAIRLINE_SPARSEST, HAIRLINE_THINNEST, HairGroom, HairStyle,
    MAX_GROOM_HAIRS, MAX_GROOM_SEGMENTS, Scalp, ScalpRoot, StrandWidths,
};
pub use surface::{GroomSurface, ScalpSurface};

use crate::schedule::HairPrepareSystems;

/// Grows procedural grooms ([`HairGroom`]) and places groom files ([`HairGroomFile`]) on their heads;
/// registers the [`GroomFile`] asset and its loaders when the app has Bevy's `AssetPlugin` (added before
/// this plugin, as `DefaultPlugins` does; without it, groom files cannot be loaded). Part of
/// [`crate::HairPlugins`].
#[derive(Debug, Clone)]
pub struct HairGroomPlugin {
    /// The fixed-timestep schedule the simulation runs in.
    pub schedule: InternedScheduleLabel,
}

impl Plugin for HairGroomPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<HairGroom>()
            .register_type::<GroomedStrand>()
            .register_type::<StrandWidths>()
            .add_systems(self.schedule, procedural::grow_groomed_hair.in_set(HairPrepareSystems::Grow));
        file::build_groom_files(app, self.schedule);
    }
}
