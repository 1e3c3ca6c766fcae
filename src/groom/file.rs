//! Grooms from files: TressFX `.tfx` and Cem Yuksel's `.hair` strand files, read into one
//! [`GroomFile`] asset by [`GroomFileLoader`] ([`HairGroomPlugin`](super::HairGroomPlugin) registers it),
//! and put on a head by [`HairGroomFile`].
//!
//! Both formats are little-endian binary. Every count and offset is checked against the file's length
//! before anything is allocated, so a truncated or corrupt file gives a [`GroomFileError`], never a
//! panic or a huge allocation.
//!
//! - **`.tfx`** (TressFX 4): a 160-byte header `f32 version, u32 strands, u32 points per strand`, then the
//!   byte offsets (0: absent) of the positions (`float4` per point, `w` marks pinned points and is not
//!   read), strand UVs (`float2` per strand), point UVs (`float2` per point), strand thickness (`f32` per
//!   strand) and point colours (`float4` per point), and 32 reserved words.
//! - **`.hair`** (Cem Yuksel, <http://www.cemyuksel.com/research/hairmodels/>): a 128-byte header
//!   `"HAIR", u32 strands, u32 points, u32 arrays` (bit 0: segments per strand, 1: points, 2: thickness,
//!   3: transparency, 4: colours), the defaults for absent arrays (`u32 segments, f32 thickness,
//!   f32 transparency, f32×3 colour`) and 88 bytes of text; then the present arrays in that order
//!   (`u16` segments per strand, `f32×3` points, `f32` thickness, `f32` transparency, `f32×3` colours per
//!   point). Strands may have different lengths.

use bevy::asset::io::Reader;
use bevy::asset::{AssetLoader, AssetPlugin, LoadContext};
use bevy::ecs::schedule::InternedScheduleLabel;
use bevy::prelude::*;
use bevy::transform::helper::TransformHelper;
use thiserror::Error;

use super::head_frame::GroomFrame;
use super::procedural::{GroomError, MAX_GROOM_SEGMENTS};
use super::surface::{GroomSurface, ScalpSurface};
use crate::followers::HairFollowers;
use crate::rod::RodMaterial;
use crate::schedule::HairPrepareSystems;
use crate::simulation::{HairHead, HairSettings, HairStrand, HeadStrands, StrandOf};

/// A strand shorter than this fraction of its groom's size (the largest side of the box around all its
/// points) is a point blurred by rounding, not a strand.
pub const MIN_RELATIVE_STRAND_LENGTH: f32 = 1e-3;

/// Fibre radii, m, that a groom file's thickness is taken as: from a fine hair to a thick fibre. A
/// thickness outside (a drawing width in pixels, TressFX's relative width) leaves the strand with the
/// default material.
pub const FIBRE_RADIUS_RANGE: std::ops::RangeInclusive<f64> = 5e-6..=5e-4;

/// Strands read from a groom file, in the file's own units and axes.
#[derive(Asset, TypePath, Debug, Clone, Default, PartialEq)]
pub struct GroomFile {
    /// Every strand's points, root first, one strand after another.
    pub points: Vec<Vec3>,
    /// Where each strand starts in [`GroomFile::points`], with the end of the last as a final entry: strand
    /// `i` is `points[strand_starts[i]..strand_starts[i + 1]]`.
    pub strand_starts: Vec<usize>,
    /// Thickness of each point, in the file's units (`.hair`: its array or default; `.tfx`: its strand
    /// thickness, a relative width, given to each of the strand's points).
    pub thickness: Option<Vec<f32>>,
    /// Transparency of each point, 0 (opaque) to 1 (`.hair` only).
    pub transparency: Option<Vec<f32>>,
    /// Colour of each point, linear RGB 0 to 1.
    pub colors: Option<Vec<Vec3>>,
    /// Texture coordinate of each strand's root on the scalp (`.tfx` only).
    pub strand_uvs: Option<Vec<Vec2>>,
    /// Texture coordinate of each point (`.tfx` only).
    pub point_uvs: Option<Vec<Vec2>>,
}

/// Why a groom file could not be read.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GroomFileError {
    /// The file could not be read.
    #[error("the groom file could not be read: {0}")]
    Io(String),
    /// The file ends before something it announces.
    #[error("the groom file is truncated: reading its {what} needs bytes up to {needed}, the file has {length}")]
    Truncated {
        /// What was being read.
        what: &'static str,
        /// The byte offset the file must reach.
        needed: u64,
        /// The file's length in bytes.
        length: usize,
    },
    /// A `.hair` file without its `HAIR` signature.
    #[error("not a .hair file: it starts with {0:?}, not \"HAIR\"")]
    Signature([u8; 4]),
    /// A header value out of its range.
    #[error("the groom file's {what} is {value}, {requirement}")]
    InvalidHeader {
        /// Which value.
        what: &'static str,
        /// The value read.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// The strands' segment counts do not add up to the file's point count.
    #[error("the .hair file's strands have {from_segments} points in all, its header says {points}")]
    PointCountMismatch {
        /// Points implied by the segment counts.
        from_segments: u64,
        /// Points in the header.
        points: u64,
    },
    /// A point whose position is NaN or infinite.
    #[error("point {point} of the groom file is not finite: {position}")]
    NonFinitePoint {
        /// Index of the point in the file.
        point: usize,
        /// Its position.
        position: Vec3,
    },
}

/// Little-endian reads from a file's bytes, each checked against its length.
struct Bytes<'a>(&'a [u8]);

impl<'a> Bytes<'a> {
    /// `count` records of `stride` bytes from `offset`, checked to lie inside the file.
    fn array(&self, what: &'static str, offset: u64, count: u64, stride: u64) -> Result<&'a [u8], GroomFileError> {
        let end = count.checked_mul(stride).and_then(|size| size.checked_add(offset));
        let length = self.0.len();
        match end {
            Some(end) if end <= length as u64 => Ok(&self.0[offset as usize..end as usize]),
            _ => Err(GroomFileError::Truncated { what, needed: end.unwrap_or(u64::MAX), length }),
        }
    }

    fn u32_at(&self, what: &'static str, offset: u64) -> Result<u32, GroomFileError> {
        let bytes = self.array(what, offset, 1, 4)?;
        Ok(u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]))
    }

    fn f32_at(&self, what: &'static str, offset: u64) -> Result<f32, GroomFileError> {
        Ok(f32::from_bits(self.u32_at(what, offset)?))
    }
}

/// The `f32`s of a checked array, `N` at a time.
fn floats<const N: usize>(bytes: &[u8]) -> impl Iterator<Item = [f32; N]> + '_ {
    bytes.chunks_exact(4 * N).map(|record| {
        std::array::from_fn(|i| {
            f32::from_le_bytes([record[4 * i], record[4 * i + 1], record[4 * i + 2], record[4 * i + 3]])
        })
    })
}

impl GroomFile {
    /// Number of strands.
    pub fn strand_count(&self) -> usize {
        self.strand_starts.len().saturating_sub(1)
    }

    /// The points of strand `index`, root first.
    pub fn strand(&self, index: usize) -> &[Vec3] {
        &self.points[self.strand_starts[index]..self.strand_starts[index + 1]]
    }

    /// The strands that can be simulated: at least 3 distinct points, and a length above
    /// [`MIN_RELATIVE_STRAND_LENGTH`] times the size of the whole groom (shorter ones are points blurred
    /// by rounding).
    pub fn usable_strands(&self) -> impl Iterator<Item = usize> + '_ {
        let (low, high) =
            self.points.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), p| (low.min(*p), high.max(*p)));
        let shortest = MIN_RELATIVE_STRAND_LENGTH * (high - low).max_element().max(0.0);
        (0..self.strand_count()).filter(move |&index| {
            let points = self.strand(index);
            let length = polyline_length(points);
            let distinct = points.windows(2).filter(|pair| pair[0] != pair[1]).count() + 1;
            distinct >= 3 && length > shortest
        })
    }

    /// Half the mean thickness of strand `index` in metres, if the file has thickness and that lies within
    /// [`FIBRE_RADIUS_RANGE`].
    pub fn fibre_radius(&self, index: usize, metres_per_unit: f32) -> Option<f64> {
        let thickness = &self.thickness.as_ref()?[self.strand_starts[index]..self.strand_starts[index + 1]];
        let mean = thickness.iter().map(|t| f64::from(*t)).sum::<f64>() / thickness.len() as f64;
        let radius = 0.5 * mean * f64::from(metres_per_unit);
        FIBRE_RADIUS_RANGE.contains(&radius).then_some(radius)
    }

    /// The file's colours of strand `index` at `edges + 1` nodes spread evenly along its length (as
    /// [`GroomFile::resampled_strand`] spreads them), blended between the file's points; `None` when the
    /// file has no colours. The file's colours are taken as linear RGB, 0 to 1.
    pub fn resampled_colors(&self, index: usize, edges: usize) -> Option<Vec<LinearRgba>> {
        let colors = self.colors.as_ref()?;
        let range = self.strand_starts[index]..self.strand_starts[index + 1];
        let (points, colors) = (&self.points[range.clone()], colors.get(range)?);
        // How far along the strand each point is (file units).
        let mut walked = 0.0;
        let along: Vec<f32> = std::iter::once(0.0)
            .chain(points.windows(2).map(|pair| pair[0].distance(pair[1])))
            .map(|step| {
                walked += step;
                walked
            })
            .collect();
        let length = walked.max(f32::MIN_POSITIVE);
        let edges = edges.max(1);
        let color = |point: usize| {
            let [r, g, b] = colors[point].clamp(Vec3::ZERO, Vec3::ONE).to_array();
            LinearRgba::rgb(r, g, b)
        };
        Some(
            (0..=edges)
                .map(|node| {
                    let at = length * node as f32 / edges as f32;
                    let after = along.partition_point(|&walked| walked < at).min(points.len() - 1);
                    if after == 0 {
                        return color(0);
                    }
                    let (from, to) = (along[after - 1], along[after]);
                    let t = if to > from { ((at - from) / (to - from)).clamp(0.0, 1.0) } else { 1.0 };
                    color(after - 1).mix(&color(after), t)
                })
                .collect(),
        )
    }

    /// Strand `index` resampled into `edges` edges of equal length, its length over `edges`, root
    /// first: each node is where the strand leaves the ball of that radius around the node before
    /// (chords along the curve). The length is kept exactly; since chords cut the bends, the tip reaches
    /// a little past the file's tip, along the strand's last direction.
    pub fn resampled_strand(&self, index: usize, edges: usize) -> Vec<Vec3> {
        let points = self.strand(index);
        let edges = edges.max(1);
        let length = polyline_length(points);
        let chord = length / edges as f32;
        let mut resampled = Vec::with_capacity(edges + 1);
        let mut current = points[0];
        resampled.push(current);
        // The walk is on segment `segment`, at `from` (a point of it).
        let (mut segment, mut from) = (0, points[0]);
        let mut direction = (points[points.len() - 1] - points[0]).normalize_or(Vec3::Y);
        for _ in 0..edges {
            let mut next = None;
            while segment + 1 < points.len() {
                let end = points[segment + 1];
                if end.distance(current) >= chord {
                    // Where `from + t (end − from)` leaves the ball: the larger root of a quadratic in t.
                    let (step, offset) = (end - from, from - current);
                    let (a, b, c) =
                        (step.length_squared(), 2.0 * offset.dot(step), offset.length_squared() - chord * chord);
                    let t = if a > 0.0 {
                        ((-b + (b * b - 4.0 * a * c).max(0.0).sqrt()) / (2.0 * a)).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    let point = from + t * step;
                    from = point;
                    next = Some(point);
                    break;
                }
                segment += 1;
                from = points[segment];
            }
            let point = next.unwrap_or(current + chord * direction);
            direction = (point - current).normalize_or(direction);
            current = point;
            resampled.push(point);
        }
        resampled
    }

    /// Reads a TressFX 4 `.tfx` file (see the module documentation).
    pub fn from_tfx(bytes: &[u8]) -> Result<Self, GroomFileError> {
        let file = Bytes(bytes);
        file.array("header", 0, 1, 160)?;
        let version = file.f32_at("version", 0)?;
        if !version.is_finite() {
            return Err(GroomFileError::InvalidHeader {
                what: "version",
                value: f64::from(version),
                requirement: "must be a finite number",
            });
        }
        let strands = u64::from(file.u32_at("strand count", 4)?);
        let per_strand = u64::from(file.u32_at("points per strand", 8)?);
        if per_strand < 2 {
            return Err(GroomFileError::InvalidHeader {
                what: "points per strand",
                value: per_strand as f64,
                requirement: "must be at least 2",
            });
        }
        let offset = |index: u64| file.u32_at("array offset", 12 + 4 * index).map(u64::from);
        let (positions, strand_uvs, point_uvs, thickness, colors) =
            (offset(0)?, offset(1)?, offset(2)?, offset(3)?, offset(4)?);
        if positions == 0 {
            return Err(GroomFileError::InvalidHeader {
                what: "position offset",
                value: 0.0,
                requirement: "must not be 0 (positions are required)",
            });
        }
        let point_count = strands.saturating_mul(per_strand);
        let positions = file.array("positions", positions, point_count, 16)?;
        let optional = |what, offset: u64, count, stride| {
            (offset != 0).then(|| file.array(what, offset, count, stride)).transpose()
        };
        let strand_uvs = optional("strand UVs", strand_uvs, strands, 8)?;
        let point_uvs = optional("point UVs", point_uvs, point_count, 8)?;
        let thickness = optional("thickness", thickness, strands, 4)?;
        let colors = optional("colours", colors, point_count, 16)?;

        let points: Vec<Vec3> = floats::<4>(positions).map(|[x, y, z, _]| Vec3::new(x, y, z)).collect();
        check_finite(&points)?;
        let per_strand = per_strand as usize;
        debug!("read a .tfx groom: {strands} strands of {per_strand} points");
        Ok(Self {
            strand_starts: (0..=strands as usize).map(|strand| strand * per_strand).collect(),
            points,
            thickness: thickness
                .map(|bytes| floats::<1>(bytes).flat_map(|[width]| std::iter::repeat_n(width, per_strand)).collect()),
            transparency: None,
            colors: colors.map(|bytes| floats::<4>(bytes).map(|[r, g, b, _]| Vec3::new(r, g, b)).collect()),
            strand_uvs: strand_uvs.map(|bytes| floats::<2>(bytes).map(Vec2::from).collect()),
            point_uvs: point_uvs.map(|bytes| floats::<2>(bytes).map(Vec2::from).collect()),
        })
    }

    /// Reads a Cem Yuksel `.hair` file (see the module documentation); absent arrays take the header's
    /// defaults.
    pub fn from_hair(bytes: &[u8]) -> Result<Self, GroomFileError> {
        let file = Bytes(bytes);
        let header = file.array("header", 0, 1, 128)?;
        let signature = [header[0], header[1], header[2], header[3]];
        if &signature != b"HAIR" {
            return Err(GroomFileError::Signature(signature));
        }
        let strands = u64::from(file.u32_at("strand count", 4)?);
        let points = u64::from(file.u32_at("point count", 8)?);
        let arrays = file.u32_at("array bits", 12)?;
        let default_segments = file.u32_at("default segments", 16)?;
        let default_thickness = file.f32_at("default thickness", 20)?;
        let default_transparency = file.f32_at("default transparency", 24)?;
        let default_color =
            Vec3::new(file.f32_at("colour", 28)?, file.f32_at("colour", 32)?, file.f32_at("colour", 36)?);
        if arrays & 2 == 0 {
            return Err(GroomFileError::InvalidHeader {
                what: "array bits",
                value: f64::from(arrays),
                requirement: "must include the points (bit 1)",
            });
        }
        let mut offset = 128;
        let mut next = |what, present: bool, count: u64, stride: u64| -> Result<Option<&[u8]>, GroomFileError> {
            if !present {
                return Ok(None);
            }
            let array = file.array(what, offset, count, stride)?;
            offset += count * stride;
            Ok(Some(array))
        };
        let segments = next("segments", arrays & 1 != 0, strands, 2)?;
        let positions = next("points", true, points, 12)?.unwrap_or_default();
        let thickness = next("thickness", arrays & 4 != 0, points, 4)?;
        let transparency = next("transparency", arrays & 8 != 0, points, 4)?;
        let colors = next("colours", arrays & 16 != 0, points, 12)?;

        if strands > points {
            return Err(GroomFileError::InvalidHeader {
                what: "strand count",
                value: strands as f64,
                requirement: "must not exceed the point count (every strand has points)",
            });
        }
        // Strand lengths, checked to add up before any per-strand memory is taken.
        let segment_count = |strand: usize| match segments {
            Some(bytes) => u64::from(u16::from_le_bytes([bytes[2 * strand], bytes[2 * strand + 1]])),
            None => u64::from(default_segments),
        };
        let from_segments: u64 = (0..strands as usize).map(|strand| segment_count(strand) + 1).sum();
        if from_segments != points {
            return Err(GroomFileError::PointCountMismatch { from_segments, points });
        }
        let mut strand_starts = Vec::with_capacity(strands as usize + 1);
        strand_starts.push(0);
        for strand in 0..strands as usize {
            strand_starts.push(strand_starts[strand] + segment_count(strand) as usize + 1);
        }
        let points: Vec<Vec3> = floats::<3>(positions).map(Vec3::from).collect();
        check_finite(&points)?;
        let per_point = |array: Option<&[u8]>, default: f32| match array {
            Some(bytes) => floats::<1>(bytes).map(|[value]| value).collect(),
            None => vec![default; points.len()],
        };
        debug!("read a .hair groom: {strands} strands, {} points", points.len());
        Ok(Self {
            thickness: Some(per_point(thickness, default_thickness)),
            transparency: Some(per_point(transparency, default_transparency)),
            colors: Some(match colors {
                Some(bytes) => floats::<3>(bytes).map(Vec3::from).collect(),
                None => vec![default_color; points.len()],
            }),
            strand_uvs: None,
            point_uvs: None,
            strand_starts,
            points,
        })
    }
}

/// The length of the polyline through `points`, in their units.
fn polyline_length(points: &[Vec3]) -> f32 {
    points.windows(2).map(|pair| pair[0].distance(pair[1])).sum()
}

/// Rejects a groom with a non-finite point.
fn check_finite(points: &[Vec3]) -> Result<(), GroomFileError> {
    match points.iter().position(|point| !point.is_finite()) {
        Some(point) => Err(GroomFileError::NonFinitePoint { point, position: points[point] }),
        None => Ok(()),
    }
}

/// Reads an asset's bytes.
async fn read_all(reader: &mut dyn Reader) -> Result<Vec<u8>, GroomFileError> {
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes).await.map_err(|error| GroomFileError::Io(error.to_string()))?;
    Ok(bytes)
}

/// Loads `.tfx` and `.hair` files as [`GroomFile`]s, telling them apart by their extension.
#[derive(Debug, Default, TypePath)]
pub struct GroomFileLoader;

impl AssetLoader for GroomFileLoader {
    type Asset = GroomFile;
    type Settings = ();
    type Error = GroomFileError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        load_context: &mut LoadContext<'_>,
    ) -> Result<GroomFile, GroomFileError> {
        let bytes = read_all(reader).await?;
        let extension = load_context.path().path().extension().and_then(|extension| extension.to_str());
        match extension {
            Some(extension) if extension.eq_ignore_ascii_case("tfx") => GroomFile::from_tfx(&bytes),
            _ => GroomFile::from_hair(&bytes),
        }
    }

    fn extensions(&self) -> &[&str] {
        &["tfx", "hair"]
    }
}

/// Which axis of a groom file points up.
#[derive(Reflect, Debug, Clone, Copy, Default, PartialEq, Eq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub enum UpAxis {
    /// +Y is up, as in Bevy (TressFX files).
    #[default]
    Y,
    /// +Z is up (many `.hair` files, Blender and Houdini exports): turned so that +Z becomes +Y.
    Z,
}

/// Where a [`GroomFile`]'s strands go on their head, and how many are simulated.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct GroomPlacement {
    /// Metres per unit of the file (0.01 for a file in centimetres). Default 1.
    pub metres_per_unit: f32,
    /// Which of the file's axes points up. Default Y.
    pub up: UpAxis,
    /// Moves the groom (in metres, after the unit conversion and the up axis) into the head's local space,
    /// with the head's scale taken out: a groom is placed at its size in metres on a scaled rig.
    pub transform: Transform,
    /// Edges per simulated strand, from 2 to [`MAX_GROOM_SEGMENTS`]: every strand is resampled to this
    /// many edges of equal length, keeping its length. Default 16.
    pub segments: usize,
    /// Most strands simulated: when the file has more, this many are picked evenly among them, and the
    /// others follow the one whose root is nearest theirs ([`GroomFile::placed_strands`]). Default 2 000.
    pub max_strands: usize,
    /// Gravity preload of every strand, 0 to 1 (see [`HairStrand::gravity_preload`]): 1, the default,
    /// makes the groom's shape the hair's shape at rest instead of sagging from it.
    pub gravity_preload: f32,
    /// Whether strands the preload cannot hold (longer than hair of their material can hold up or out)
    /// are stiffened until they hold (see [`HairStrand::stiffen_to_hold`]). Default `true`: a groom is
    /// authored as it should look, whether gel, clumping or a scale larger than life holds it.
    pub stiffen_to_hold: bool,
    /// Whether the groom is fitted to its head's scalp mesh ([`GroomSurface`], from
    /// [`HairScalpMesh`](crate::scalp::HairScalpMesh)) before it is placed: scaled and moved so that its
    /// roots lie on the scalp ([`GroomPlacement::fitted_to`]). Default `false`: placed as given.
    pub fit_to_scalp: bool,
}

impl Default for GroomPlacement {
    fn default() -> Self {
        Self {
            metres_per_unit: 1.0,
            up: UpAxis::Y,
            transform: Transform::IDENTITY,
            segments: 16,
            max_strands: 2000,
            gravity_preload: 1.0,
            stiffen_to_hold: true,
            fit_to_scalp: false,
        }
    }
}

impl GroomPlacement {
    /// Checks that the unit is positive and finite, the transform finite (and not flattened by a zero
    /// scale), the segments from 2 to [`MAX_GROOM_SEGMENTS`] and the gravity preload from 0 to 1.
    pub fn validate(&self) -> Result<(), GroomError> {
        let invalid = |what, value: f64, requirement| Err(GroomError::InvalidPlacement { what, value, requirement });
        if !(self.metres_per_unit.is_finite() && self.metres_per_unit > 0.0) {
            return invalid("metres_per_unit", self.metres_per_unit.into(), "must be positive and finite");
        }
        if !self.transform.is_finite() || self.transform.scale.abs().min_element() == 0.0 {
            return invalid("transform", f64::NAN, "must be finite, with no zero scale");
        }
        if !(2..=MAX_GROOM_SEGMENTS).contains(&self.segments) {
            return invalid("segments", self.segments as f64, "must be from 2 to MAX_GROOM_SEGMENTS (1024)");
        }
        if !(0.0..=1.0).contains(&self.gravity_preload) {
            return invalid("gravity_preload", self.gravity_preload.into(), "must lie in 0 to 1");
        }
        Ok(())
    }

    /// A file point (file units and axes) in the head's local space, m.
    pub fn place(&self, point: Vec3) -> Vec3 {
        let point = match self.up {
            UpAxis::Y => point,
            UpAxis::Z => Vec3::new(point.x, point.z, -point.y),
        };
        self.transform.transform_point(point * self.metres_per_unit)
    }

    /// This placement scaled and moved so that `file`'s roots lie on `surface` (head-local), keeping its
    /// turn and up axis:
    ///
    /// - **scale**: the largest by which the roots' extent along each axis over which they spread (at
    ///   least half as far as along their widest) still fits the surface's, so that a groom with roots
    ///   all over its head fills a scalp and a crest of roots runs the scalp's length;
    /// - **offset**: the roots' bounds centred on the surface's, then moved by their mean distance to the
    ///   surface's nearest points until that is below a micrometre (at most 64 times; iterative closest
    ///   points with translation only);
    /// - then both, by least squares onto the nearest points (at most 64 times), while that brings the
    ///   roots nearer the surface and keeps the scale within a factor of two of the first.
    ///
    /// The fibres' radius scales with the unit. A file without usable strands keeps this placement.
    pub fn fitted_to(&self, file: &GroomFile, surface: &ScalpSurface) -> Self {
        let roots: Vec<Vec3> = file.usable_strands().map(|index| self.place(file.strand(index)[0])).collect();
        let (low, high) = roots
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(low, high), &root| (low.min(root), high.max(root)));
        let (scalp_low, scalp_high) = surface.bounds();
        let (extent, scalp_extent) = (high - low, scalp_high - scalp_low);
        let widest = extent.max_element();
        let mut scale = (0..3)
            .filter(|&axis| extent[axis] >= 0.5 * widest && extent[axis] > 0.0)
            .map(|axis| scalp_extent[axis] / extent[axis])
            .fold(f32::INFINITY, f32::min);
        if roots.is_empty() || !scale.is_finite() || scale <= 0.0 {
            return *self;
        }
        let centre = 0.5 * (low + high);
        let count = roots.len() as f32;
        let mut offset = 0.5 * (scalp_low + scalp_high) - centre;
        let placed =
            |scale: f32, offset: Vec3| roots.iter().map(move |&root| centre + scale * (root - centre) + offset);
        for _ in 0..64 {
            let moved = placed(scale, offset).map(|point| surface.nearest(point).0 - point).sum::<Vec3>() / count;
            offset += moved;
            if moved.length() < 1e-6 {
                break;
            }
        }
        // Then scale and offset together, by least squares onto the nearest points, while that brings the
        // roots nearer and keeps the scale within a factor of two of the extents'.
        // The roots placed by a scale and offset, each with its nearest point of the surface, and their
        // RMS distance.
        let paired = |scale: f32, offset: Vec3| -> (Vec<Vec3>, Vec<Vec3>) {
            placed(scale, offset).map(|point| (point, surface.nearest(point).0)).unzip()
        };
        let rms = |(points, nearest): &(Vec<Vec3>, Vec<Vec3>)| {
            (points.iter().zip(nearest).map(|(p, q)| p.distance_squared(*q)).sum::<f32>() / count).sqrt()
        };
        let from_extents = scale;
        let mut pairs = paired(scale, offset);
        let mut distance = rms(&pairs);
        for _ in 0..64 {
            let (points, nearest) = &pairs;
            let (mean, mean_nearest) = (points.iter().sum::<Vec3>() / count, nearest.iter().sum::<Vec3>() / count);
            let spread: f32 = points.iter().map(|point| (*point - mean).length_squared()).sum();
            let along: f32 = points.iter().zip(nearest).map(|(p, q)| (*p - mean).dot(*q - mean_nearest)).sum();
            let factor = along / spread;
            if !(factor.is_finite() && factor > 0.0) {
                break;
            }
            // The roots (about `centre`, by `scale`, then `offset`) scaled by `factor` about their mean and
            // moved onto the nearest points' mean.
            let (next_scale, next_offset) = (scale * factor, mean_nearest + factor * (centre + offset - mean) - centre);
            let next_pairs = paired(next_scale, next_offset);
            let next_distance = rms(&next_pairs);
            if next_distance.partial_cmp(&distance) != Some(std::cmp::Ordering::Less)
                || !(0.5..=2.0).contains(&(next_scale / from_extents))
            {
                break;
            }
            (scale, offset, distance, pairs) = (next_scale, next_offset, next_distance, next_pairs);
        }
        // place'(p) = t' + s (place(p) − t) = s (place(p) − centre) + centre + offset.
        let translation = scale * (self.transform.translation - centre) + centre + offset;
        Self {
            metres_per_unit: self.metres_per_unit * scale,
            transform: self.transform.with_translation(translation),
            ..*self
        }
    }
}

/// A groom from a file on a head ([`HairHead`]): its strands, placed by [`GroomPlacement`], become the
/// head's simulated strands once the file is loaded. On a head with a scalp mesh
/// ([`HairScalpMesh`](crate::scalp::HairScalpMesh)) each strand is moved, whole, until its root lies on
/// the scalp's nearest point (where the root is then bound), once the scalp's shape is known. Changing the component, or the file (hot
/// reloading), regrows them; a file that fails to load leaves the head's hair as it was (the asset
/// server logs why).
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_hair_sim::prelude::*;
/// fn spawn(mut commands: Commands, assets: Res<AssetServer>) {
///     let groom = HairGroomFile::new(assets.load("grooms/Ratboy_mohawk.tfx"));
///     commands.spawn((HairHead, groom, Transform::from_xyz(0.0, 1.2, 0.0)));
/// }
/// ```
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Debug, Clone, PartialEq)]
#[require(HairHead)]
pub struct HairGroomFile {
    /// The groom file.
    pub file: Handle<GroomFile>,
    /// Where its strands go and how many.
    pub placement: GroomPlacement,
}

impl HairGroomFile {
    /// The groom of `file`, placed as it is (metres, +Y up), 16 edges per strand, at most 2 000 strands.
    pub fn new(file: Handle<GroomFile>) -> Self {
        Self { file, placement: GroomPlacement::default() }
    }

    /// With `placement`.
    pub fn with_placement(mut self, placement: GroomPlacement) -> Self {
        self.placement = placement;
        self
    }
}

/// Marks a strand placed from a head's [`HairGroomFile`]: placing it again replaces these and keeps the
/// head's other strands.
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone)]
pub struct FileStrand;

/// The colours a strand is drawn in, hair by hair and node by node (root first), linear RGB: the
/// guide's, then each of its followers' in the order of its [`HairFollowers::curves`]. A placed groom
/// file gives it to its strands when the file has colours; give it to strands of your own to colour
/// them hair by hair. The renderer reads it when it lays the head's hair out (when the strands are
/// spawned or change); a hair it names no colours for, or with another number of colours than nodes, is
/// drawn in its head's [`HairAppearance`](crate::render::HairAppearance) colours.
#[derive(Component, Reflect, Debug, Clone, Default, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct StrandColors {
    /// Per drawn hair (the guide first), per node: its colour.
    pub hairs: Vec<Vec<LinearRgba>>,
}

/// On a head whose [`HairGroomFile`] has been placed: which file version it was placed from.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct PlacedGroomFile(AssetId<GroomFile>);

impl GroomFile {
    /// The strands to simulate for `placement`, head-local (m), with their followers: the usable strands
    /// (see [`GroomFile::usable_strands`]), at most `max_strands` picked evenly as guides, each resampled
    /// to `segments` edges; every usable strand not picked becomes a follower of the guide whose root is
    /// nearest its own, resampled alike, so that all the file's hair is drawn. A guide whose mean
    /// thickness in metres makes a fibre radius within [`FIBRE_RADIUS_RANGE`] gets `material` with that
    /// radius (so a `.hair` file in real units gives its fibres' thickness); others follow the default
    /// material. Each guide is preloaded against gravity and stiffened to hold as `placement` says. An
    /// invalid `placement` ([`GroomPlacement::validate`]) places none.
    pub fn placed_strands(&self, placement: &GroomPlacement, material: &RodMaterial) -> PlacedStrands {
        if placement.validate().is_err() {
            return PlacedStrands::default();
        }
        let usable: Vec<usize> = self.usable_strands().collect();
        let skipped = self.strand_count() - usable.len();
        let count = usable.len().min(placement.max_strands);
        let edges = placement.segments.max(2);
        let placed = |index: usize| -> Vec<Vec3> {
            let points = self.resampled_strand(index, edges);
            points.into_iter().map(|point| placement.place(point)).collect()
        };
        // One per guide when the file has colours (a strand it has none for gets an empty list: drawn in
        // the appearance's colours), so that they stay in step with the guides.
        let colored = self.colors.is_some();
        let strand_colors = |index: usize| self.resampled_colors(index, edges).unwrap_or_default();
        let mut colors: Vec<StrandColors> = Vec::new();
        let mut picked = vec![false; usable.len()];
        let mut guides: Vec<(HairStrand, HairFollowers)> = (0..count)
            .map(|pick| {
                let which = pick * usable.len() / count;
                picked[which] = true;
                let index = usable[which];
                if colored {
                    colors.push(StrandColors { hairs: vec![strand_colors(index)] });
                }
                let nodes = placed(index);
                let direction = (nodes[1] - nodes[0]).any_orthonormal_vector();
                let strand = HairStrand::from_nodes(nodes, direction)
                    .with_gravity_preload(placement.gravity_preload)
                    .with_stiffening_to_hold(placement.stiffen_to_hold);
                let strand = match self.fibre_radius(index, placement.metres_per_unit) {
                    Some(radius) => {
                        strand.with_material(RodMaterial { semi_axis_1: radius, semi_axis_2: radius, ..*material })
                    }
                    None => strand,
                };
                (strand, HairFollowers::default())
            })
            .collect();
        // Each follower to the guide with the nearest root: a pass over the guides per follower.
        let roots: Vec<Vec3> = guides.iter().map(|(strand, _)| strand.nodes[0]).collect();
        for (&index, _) in usable.iter().zip(&picked).filter(|(_, picked)| !**picked) {
            let nodes = placed(index);
            let nearest = roots
                .iter()
                .enumerate()
                .min_by(|(_, a), (_, b)| a.distance_squared(nodes[0]).total_cmp(&b.distance_squared(nodes[0])));
            if let Some((guide, _)) = nearest {
                guides[guide].1.curves.push(nodes);
                if colored {
                    colors[guide].hairs.push(strand_colors(index));
                }
            }
        }
        PlacedStrands { guides, colors, skipped }
    }
}

/// A [`GroomFile`] placed on a head ([`GroomFile::placed_strands`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlacedStrands {
    /// The strands to simulate (head-local, m), each with its followers: the file's strands that are not
    /// simulated, each given to the guide whose root is nearest its own.
    pub guides: Vec<(HairStrand, HairFollowers)>,
    /// The file's colours of each guide and its followers, one per guide in the same order; empty when
    /// the file has no colours.
    pub colors: Vec<StrandColors>,
    /// How many of the file's strands were skipped as degenerate (fewer than 3 distinct points, or no
    /// length).
    pub skipped: usize,
}

impl PlacedStrands {
    /// How many of the file's strands are drawn: the guides and their followers.
    pub fn drawn_strands(&self) -> usize {
        self.guides.iter().map(|(_, followers)| 1 + followers.curves.len()).sum()
    }
}

/// Heads with a groom file, what they were placed from, and their strands.
type GroomFileHeads<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        Ref<'static, HairGroomFile>,
        Option<&'static PlacedGroomFile>,
        Option<&'static HeadStrands>,
        Option<Ref<'static, GroomSurface>>,
    ),
>;

/// Places the strands of every head whose [`HairGroomFile`] is new, changed, newly loaded or reloaded,
/// replacing the strands it placed before.
fn place_groom_files(
    mut commands: Commands,
    mut events: MessageReader<AssetEvent<GroomFile>>,
    files: Res<Assets<GroomFile>>,
    settings: Res<HairSettings>,
    heads: GroomFileHeads,
    placed: Query<(), With<FileStrand>>,
    transforms: TransformHelper,
) {
    let reloaded: Vec<AssetId<GroomFile>> = events
        .read()
        .filter_map(|event| match event {
            AssetEvent::Modified { id } => Some(*id),
            _ => None,
        })
        .collect();
    for (head, groom, placed_from, strands, surface) in &heads {
        let id = groom.file.id();
        let fit = groom.placement.fit_to_scalp;
        // Placed onto its scalp (and fitted to it, if asked): a new shape of the scalp places it again.
        let reshaped = surface.as_ref().is_some_and(|surface| surface.is_changed());
        let stale =
            groom.is_changed() || placed_from != Some(&PlacedGroomFile(id)) || reloaded.contains(&id) || reshaped;
        let Some(file) = files.get(id).filter(|_| stale) else {
            continue;
        };
        // On a scalp that is not known yet: wait for it.
        if matches!(surface.as_deref(), Some(GroomSurface::Waiting)) {
            continue;
        }
        // Placed in metres on a scaled head (its scale taken out), then given to it.
        let frame = GroomFrame::of_head(head, &transforms);
        let scaled_surface = match frame.surface_of(surface.as_deref()) {
            Ok(scaled) => scaled,
            Err(error) => {
                error!("hair groom file of head {head}: its scalp cannot be used ({error}); no strands are placed");
                continue;
            }
        };
        let scalp = scaled_surface.as_ref().map(GroomSurface::surface);
        let placement = match scalp.flatten() {
            Some(scalp) if fit => groom.placement.fitted_to(file, scalp),
            _ => {
                if fit && groom.is_changed() {
                    warn!(
                        "hair groom file of head {head}: fit_to_scalp, but the head has no HairScalpMesh; placed as given"
                    );
                }
                groom.placement
            }
        };
        for &strand in strands.map_or(&[][..], HeadStrands::strands) {
            if placed.contains(strand) {
                commands.entity(strand).despawn();
            }
        }
        if let Err(error) = placement.validate() {
            if groom.is_changed() {
                error!("hair groom file of head {head}: {error}; no strands are placed until it is fixed");
            }
            continue;
        }
        let PlacedStrands { mut guides, colors, skipped } = file.placed_strands(&placement, &settings.default_material);
        if let Some(scalp) = scalp.flatten() {
            for (guide, followers) in &mut guides {
                scalp.move_onto(&mut guide.nodes);
                followers.curves.iter_mut().for_each(|curve| scalp.move_onto(curve));
            }
        }
        frame.grown_to_head(&mut guides);
        if skipped > 0 {
            warn!(
                "hair groom file of head {head}: {skipped} degenerate strands (fewer than 3 distinct points, or no length) skipped"
            );
        }
        let placed = guides.into_iter().map(move |(strand, followers)| (strand, followers, StrandOf(head), FileStrand));
        if colors.len() == placed.len() {
            commands.spawn_batch(placed.zip(colors));
        } else {
            commands.spawn_batch(placed);
        }
        commands.entity(head).insert(PlacedGroomFile(id));
    }
}

/// Registers the [`GroomFile`] asset and its loaders, and places [`HairGroomFile`]s on their heads in
/// [`HairPrepareSystems::Grow`], when the app has Bevy's `AssetPlugin` (added before this plugin, as
/// `DefaultPlugins` does); without it, groom files cannot be loaded.
pub(super) fn build_groom_files(app: &mut App, schedule: InternedScheduleLabel) {
    if !app.is_plugin_added::<AssetPlugin>() {
        debug!("HairGroomPlugin: no AssetPlugin, so groom files cannot be loaded");
        return;
    }
    app.init_asset::<GroomFile>()
        .init_asset_loader::<GroomFileLoader>()
        .register_type::<FileStrand>()
        .register_type::<HairGroomFile>()
        .register_type::<StrandColors>()
        .add_systems(schedule, place_groom_files.in_set(HairPrepareSystems::Grow));
}
