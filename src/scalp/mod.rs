//! Roots bound to a scalp mesh: hair that grows from a character's skin, rigid or skinned.
//!
//! Put [`HairScalpMesh`]`(mesh_entity)` on a head: every strand of that head ([`StrandOf`]) is bound, once
//! the mesh has loaded, to the triangle of the mesh nearest its root (a [`ScalpRootBinding`]: the triangle
//! and the root's barycentric coordinates in it). From then on, every fixed step, the root follows that
//! point of the triangle as the mesh is drawn, and the root edge keeps its direction in the triangle's
//! frame (its first edge, its normal):
//!
//! - a **skinned** mesh ([`SkinnedMesh`]) is skinned on the CPU as Bevy's shaders skin it (each corner by
//!   its joints' `GlobalTransform` × inverse bind pose, blended by its weights), and only the corners of
//!   bound triangles are;
//! - a mesh without a skin moves with its entity's `GlobalTransform`.
//!
//! The head should be the entity that moves most like the scalp (the head joint of a skeleton): the
//! head's pose still carries the whole strand when it teleports, chooses its level of detail and places
//! a quarantined strand, and the roots' anchors are kept in its local space.
//!
//! ```
//! # use bevy::prelude::*;
//! # use bevy_hair_sim::prelude::*;
//! # let mut world = World::new();
//! # let scalp = world.spawn_empty().id();
//! // Once the character is spawned: its head joint becomes the hair's head, its scalp mesh the binding.
//! let head_joint = world.spawn((Transform::default(), HairHead, HairScalpMesh(scalp))).id();
//! world.entity_mut(head_joint).insert(HairGroom::default());
//! ```
//!
//! **A character from a glTF file**: [`HairOnCharacter`] on its scene's root finds the head joint, the
//! scalp and the collider meshes by name once the scene has spawned, and puts the hair on them.
//!
//! Strands are bound in the pose the mesh has when they are first stepped, so spawn the hair with the
//! roots on the scalp as it is then. A root is bound to the nearest point of the mesh wherever it is;
//! what it needs is a triangle list with positions in the main world (and, skinned, joint indices and
//! weights). A mesh that cannot be used is reported once and its head's roots follow the head until it
//! is fixed.

use std::sync::Arc;

use bevy::math::{Affine3A, DAffine3, DMat3, DVec3};
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::transform::helper::TransformHelper;
use thiserror::Error;

mod character;

pub use character::{CharacterHair, HairOnCharacter, HairOnCharacterStatus};

use crate::collision::mesh::{MeshColliderError, mesh_triangles};
use crate::groom::{GroomError, GroomSurface, HairGroom, HairGroomFile, ScalpSurface};
use crate::rod::{barycentric, closest_point_on_triangle};
use crate::schedule::{HairPinSystems, HairPrepareSystems, HairSystems};
use crate::simulation::{HairStrand, HeadMotion, SimulatedStrand, StrandOf};

/// On a [`HairHead`](crate::simulation::HairHead): its strands' roots are bound to the triangles of this
/// entity's [`Mesh3d`] (skinned by its [`SkinnedMesh`] if it has one). See the [module documentation](self).
#[derive(Component, Reflect, Debug, Clone, Copy, PartialEq, Eq)]
#[reflect(Component, Debug, PartialEq, Clone)]
#[require(ScalpPose, GroomSurface)]
pub struct HairScalpMesh(pub Entity);

/// On a [`HairHead`](crate::simulation::HairHead) with a [`HairScalpMesh`]: hair grows on the scalp mesh
/// where the head joint skins it, each vertex's density its weight for the head (see
/// [`ScalpSurface`]), instead of the density painted in the mesh's vertex
/// colours. For a character that is one skinned mesh from head to tail: the head's own triangles become
/// its scalp. [`HairOnCharacter::with_scalp_where_head_skins`] puts it on.
#[derive(Component, Reflect, Debug, Clone, Copy, Default, PartialEq, Eq)]
#[reflect(Component, Debug, Default, PartialEq, Clone)]
pub struct ScalpWhereHeadSkins;

/// Where a strand's root is bound on its head's scalp mesh; added by the plugin.
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Debug, PartialEq, Clone)]
pub struct ScalpRootBinding {
    /// The scalp mesh entity bound to.
    pub mesh: Entity,
    /// The triangle's index in the mesh (its corners are indices `3 · triangle` to `3 · triangle + 2`).
    pub triangle: u32,
    /// The root's barycentric coordinates in the triangle (weights of its three corners, summing to 1).
    pub barycentric: DVec3,
    /// The triangle's corners as the mesh has them, with their joints.
    pub corners: [BoundVertex; 3],
    /// The root edge's direction in the triangle's frame (first edge, second, normal).
    edge_direction: DVec3,
    /// The root edge's material direction in the triangle's frame.
    material_direction: DVec3,
}

/// A corner of a bound triangle: its position in the mesh's space, m, and the joints that skin it.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, PartialEq, Clone)]
pub struct BoundVertex {
    /// Position in the mesh's (bind) space, m.
    pub position: Vec3,
    /// Indices into the [`SkinnedMesh::joints`] (all 0 for a mesh without a skin).
    pub joints: [u16; 4],
    /// Weights of those joints, summing to 1.
    pub weights: [f32; 4],
}

/// Where a head's scalp mesh is at this step: each joint's map from the mesh's space to the head's local
/// space (one map, the mesh entity's, for a mesh without a skin). Kept by the plugin.
#[derive(Component, Debug, Default, Clone)]
pub struct ScalpPose {
    /// The maps, or `None` while the scalp cannot be posed (not loaded, or faulty).
    joints: Option<Vec<DAffine3>>,
    /// Why it cannot be, when it is faulty (reported once).
    problem: Option<ScalpError>,
    /// Why the posed mesh cannot bind roots or grow a groom, when it cannot (reported once; the pose's
    /// problem is cleared each step it can be posed, this one when the scalp changes or grows a groom).
    /// Binding and growing read the same mesh, so they share it.
    mesh_problem: Option<ScalpError>,
}

impl ScalpPose {
    /// Where the mesh-space `vertex` is, in the head's local space, m: the blend of its joints' maps.
    fn skin(joints: &[DAffine3], vertex: &BoundVertex) -> Option<DVec3> {
        let position = vertex.position.as_dvec3();
        vertex.joints.iter().zip(vertex.weights).try_fold(DVec3::ZERO, |sum, (&joint, weight)| {
            if weight == 0.0 {
                return Some(sum);
            }
            Some(sum + f64::from(weight) * joints.get(usize::from(joint))?.transform_point3(position))
        })
    }
}

/// Why a scalp mesh cannot hold roots.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ScalpError {
    /// The scalp entity has no `Mesh3d`.
    #[error("the scalp entity {0} has no Mesh3d")]
    NoMesh(Entity),
    /// A transform of the mesh or a joint is missing or not finite.
    #[error("the scalp mesh or one of its joints has no usable transform")]
    NoTransform,
    /// The skin's joints and inverse bind poses do not match.
    #[error("the skin has {joints} joints but {bindposes} inverse bind poses")]
    SkinMismatch {
        /// Joints in the [`SkinnedMesh`].
        joints: usize,
        /// Inverse bind poses in its asset.
        bindposes: usize,
    },
    /// A skinned mesh without `u16 × 4` joint indices and `f32 × 4` weights for every vertex.
    #[error("the skinned scalp mesh has no joint indices and weights for every vertex")]
    NoJointWeights,
    /// A vertex's weights do not sum to a positive number, or name a joint the skin does not have.
    #[error("vertex {0} of the scalp mesh has no joint weight, or a joint the skin does not have")]
    BadWeights(u32),
    /// Every triangle is degenerate.
    #[error("the scalp mesh has no triangle with an area")]
    NoTriangle,
    /// The mesh's data.
    #[error(transparent)]
    Mesh(#[from] MeshColliderError),
    /// The mesh cannot grow a groom.
    #[error(transparent)]
    Surface(#[from] GroomError),
}

/// Roots bound to scalp meshes (see the [module documentation](self)); part of [`crate::HairPlugins`].
#[derive(Debug, Clone)]
pub struct HairScalpPlugin {
    /// The fixed-timestep schedule the simulation runs in (that of [`crate::HairSimulationPlugin`]).
    pub schedule: bevy::ecs::schedule::InternedScheduleLabel,
}

impl Plugin for HairScalpPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<HairScalpMesh>()
            .register_type::<ScalpRootBinding>()
            .register_type::<HairOnCharacter>()
            .register_type::<HairOnCharacterStatus>()
            .register_type::<ScalpWhereHeadSkins>()
            .add_systems(
                self.schedule,
                (pose_scalps, bind_roots, follow_scalps).chain().in_set(HairPinSystems::FollowScalp),
            )
            .add_systems(
                self.schedule,
                shape_groom_surfaces.in_set(HairSystems::Prepare).before(HairPrepareSystems::Grow),
            )
            .add_systems(Update, character::attach_hair_to_characters);
    }
}

/// Every scalp's joint maps for this step, from the joints' transforms now (computed through their
/// parents, as the heads' are) and the head's pose.
fn pose_scalps(
    transforms: TransformHelper,
    meshes: Query<(Has<Mesh3d>, Option<&SkinnedMesh>)>,
    bindposes: Option<Res<Assets<SkinnedMeshInverseBindposes>>>,
    mut heads: Query<(Entity, &HairScalpMesh, &HeadMotion, &mut ScalpPose)>,
    mut unbound: Query<&mut ScalpPose, Without<HairScalpMesh>>,
) {
    // A head whose scalp was taken away: its roots stay where they were on it.
    for mut pose in &mut unbound {
        if pose.joints.is_some() {
            pose.joints = None;
        }
    }
    for (head, &HairScalpMesh(scalp), motion, mut pose) in &mut heads {
        let head_pose = motion.current;
        let to_head =
            DAffine3::from_scale_rotation_translation(head_pose.scale, head_pose.rotation, head_pose.translation)
                .inverse();
        match scalp_joints(scalp, to_head, &transforms, &meshes, bindposes.as_deref()) {
            Ok(joints) => {
                pose.joints = Some(joints);
                pose.problem = None;
            }
            Err(problem) => {
                pose.joints = None;
                report(head, &mut pose.problem, problem);
            }
        }
    }
}

/// The maps from the mesh space of `scalp` into the space `to_head` maps the world into: one per joint
/// (the joint's `GlobalTransform` × its inverse bind pose), or the mesh entity's own without a skin. Err
/// `None` while the skin is loading.
fn scalp_joints(
    scalp: Entity,
    to_head: DAffine3,
    transforms: &TransformHelper,
    meshes: &Query<(Has<Mesh3d>, Option<&SkinnedMesh>)>,
    bindposes: Option<&Assets<SkinnedMeshInverseBindposes>>,
) -> Result<Vec<DAffine3>, Option<ScalpError>> {
    let global = |entity: Entity| {
        transforms
            .compute_global_transform(entity)
            .ok()
            .map(|transform| affine_f64(transform.affine()))
            .filter(|affine| affine.is_finite())
            .ok_or(ScalpError::NoTransform)
    };
    match meshes.get(scalp) {
        Ok((false, _)) | Err(_) => Err(Some(ScalpError::NoMesh(scalp))),
        Ok((true, None)) => global(scalp).map(|mesh| vec![to_head * mesh]).map_err(Some),
        Ok((true, Some(skin))) => match bindposes.and_then(|assets| assets.get(&skin.inverse_bindposes)) {
            None => Err(None), // Not loaded yet.
            Some(inverse) if inverse.len() != skin.joints.len() => {
                Err(Some(ScalpError::SkinMismatch { joints: skin.joints.len(), bindposes: inverse.len() }))
            }
            Some(inverse) => skin
                .joints
                .iter()
                .zip(inverse.iter())
                .map(|(&joint, bindpose)| Ok(to_head * global(joint)? * affine_f64(Affine3A::from_mat4(*bindpose))))
                .collect::<Result<Vec<_>, _>>()
                .map_err(Some),
        },
    }
}

/// Heads with a scalp mesh, and what may need their groom surface anew.
type SurfaceHeads<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        Ref<'static, HairScalpMesh>,
        &'static mut GroomSurface,
        &'static mut ScalpPose,
        Option<Ref<'static, HairGroom>>,
        Option<Ref<'static, HairGroomFile>>,
        Has<ScalpWhereHeadSkins>,
    ),
>;

/// Gives every head with a scalp mesh and a groom or groom file whose surface is still waiting, or whose
/// scalp, groom or groom file is new or changed, its [`GroomSurface`]: the scalp mesh as it is posed now, in the head's local space,
/// with the hair density painted in its vertex colours.
fn shape_groom_surfaces(
    transforms: TransformHelper,
    meshes: Option<Res<Assets<Mesh>>>,
    scalp_meshes: Query<(Has<Mesh3d>, Option<&SkinnedMesh>)>,
    handles: Query<(&Mesh3d, Has<SkinnedMesh>)>,
    bindposes: Option<Res<Assets<SkinnedMeshInverseBindposes>>>,
    mut heads: SurfaceHeads,
) {
    for (head, scalp, mut surface, mut pose, groom, file, where_head_skins) in &mut heads {
        // A new scalp may do what the last could not: its problems are said anew (this runs first of
        // the scalp's systems in a step).
        if scalp.is_changed() && pose.mesh_problem.is_some() {
            pose.mesh_problem = None;
        }
        // Only a groom grows on it.
        if groom.is_none() && file.is_none() {
            continue;
        }
        let regrow = groom.is_some_and(|groom| groom.is_changed()) || file.is_some_and(|file| file.is_changed());
        if !(matches!(*surface, GroomSurface::Waiting) || scalp.is_changed() || regrow) {
            continue;
        }
        let Some(to_head) = transforms
            .compute_global_transform(head)
            .ok()
            .map(|transform| affine_f64(transform.affine()))
            .filter(|affine| affine.is_finite() && affine.matrix3.determinant() != 0.0)
        else {
            report(head, &mut pose.mesh_problem, Some(ScalpError::NoTransform));
            continue;
        };
        let shaped = scalp_joints(scalp.0, to_head.inverse(), &transforms, &scalp_meshes, bindposes.as_deref())
            .and_then(|joints| {
                let (mesh3d, skinned) = handles.get(scalp.0).map_err(|_| Some(ScalpError::NoMesh(scalp.0)))?;
                let mesh = meshes.as_ref().and_then(|meshes| meshes.get(&mesh3d.0)).ok_or(None)?;
                let posed = PosedScalp::new(mesh, skinned, &joints).map_err(Some)?;
                let positions = posed.posed.iter().map(|position| position.as_vec3()).collect();
                let head_weights = where_head_skins
                    .then(|| scalp_meshes.get(scalp.0).ok().and_then(|(_, skin)| joint_weights(mesh, skin?, head)))
                    .flatten();
                let shaped = ScalpSurface::new(positions, posed.triangles).and_then(|shaped| match head_weights {
                    Some(weights) => shaped.with_density(weights),
                    None => shaped.painted_by(mesh),
                });
                shaped.map_err(|error| Some(error.into()))
            });
        match shaped {
            Ok(shaped) => {
                *surface = GroomSurface::Ready(Arc::new(shaped));
                pose.mesh_problem = None;
            }
            // Waiting (and the groom with it) until the mesh has loaded, or is fixed.
            Err(problem) => {
                if !matches!(*surface, GroomSurface::Waiting) {
                    *surface = GroomSurface::Waiting;
                }
                report(head, &mut pose.mesh_problem, problem);
            }
        }
    }
}

/// Each vertex's weight for the joint `joint` in `mesh` skinned by `skin`, 0 to 1; `None` if the skin does
/// not name the joint or the mesh has no weights.
fn joint_weights(mesh: &Mesh, skin: &SkinnedMesh, joint: Entity) -> Option<Vec<f32>> {
    let index = skin.joints.iter().position(|&entity| entity == joint)?;
    let indices: Vec<[u16; 4]> = match mesh.try_attribute(Mesh::ATTRIBUTE_JOINT_INDEX).ok()? {
        VertexAttributeValues::Uint16x4(indices) => indices.clone(),
        VertexAttributeValues::Uint8x4(indices) => indices.iter().map(|index| index.map(u16::from)).collect(),
        _ => return None,
    };
    let VertexAttributeValues::Float32x4(weights) = mesh.try_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT).ok()? else {
        return None;
    };
    let weight = |(joints, weights): (&[u16; 4], &[f32; 4])| {
        (0..4).filter(|&k| usize::from(joints[k]) == index).map(|k| weights[k]).sum::<f32>().clamp(0.0, 1.0)
    };
    Some(indices.iter().zip(weights).map(weight).collect())
}

/// Records `problem` on the head's scalp in `slot`, logging it when it is new.
fn report(head: Entity, slot: &mut Option<ScalpError>, problem: Option<ScalpError>) {
    if problem.is_some() && *slot != problem {
        if let Some(problem) = &problem {
            error!("hair head {head}: its scalp mesh cannot hold roots or grow hair, and waits: {problem}");
        }
        *slot = problem;
    }
}

/// A single-precision affine map in double precision.
fn affine_f64(affine: Affine3A) -> DAffine3 {
    DAffine3::from_mat4(Mat4::from(affine).as_dmat4())
}

/// A scalp's triangles, posed in the head's local space, with their corners.
struct PosedScalp {
    corners: Vec<BoundVertex>,
    triangles: Vec<[u32; 3]>,
    posed: Vec<DVec3>,
}

impl PosedScalp {
    /// Reads `mesh` (skinned when `skinned`) and poses it with `joints`.
    fn new(mesh: &Mesh, skinned: bool, joints: &[DAffine3]) -> Result<Self, ScalpError> {
        let (positions, triangles) = mesh_triangles(mesh, Affine3A::IDENTITY)?;
        let count = positions.len();
        let (indices, weights) = if skinned {
            match (mesh.try_attribute(Mesh::ATTRIBUTE_JOINT_INDEX), mesh.try_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT)) {
                (Ok(VertexAttributeValues::Uint16x4(indices)), Ok(VertexAttributeValues::Float32x4(weights)))
                    if indices.len() == count && weights.len() == count =>
                {
                    (indices.clone(), weights.clone())
                }
                _ => return Err(ScalpError::NoJointWeights),
            }
        } else {
            (vec![[0; 4]; count], vec![[1.0, 0.0, 0.0, 0.0]; count])
        };
        let corners = positions
            .iter()
            .zip(indices.into_iter().zip(weights))
            .enumerate()
            .map(|(vertex, (position, (joints, weights)))| {
                let sum: f32 = weights.iter().sum();
                if !(sum > 0.0 && sum.is_finite() && weights.iter().all(|&weight| weight >= 0.0)) {
                    return Err(ScalpError::BadWeights(vertex as u32));
                }
                Ok(BoundVertex { position: position.as_vec3(), joints, weights: weights.map(|weight| weight / sum) })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let posed = corners
            .iter()
            .enumerate()
            .map(|(vertex, corner)| ScalpPose::skin(joints, corner).ok_or(ScalpError::BadWeights(vertex as u32)))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { corners, triangles, posed })
    }

    /// The triangle nearest `point` (head-local, m) with an area, and the nearest point's barycentric
    /// coordinates in it.
    fn nearest(&self, point: DVec3) -> Option<(u32, DVec3)> {
        let mut best: Option<(f64, u32, DVec3)> = None;
        for (index, triangle) in self.triangles.iter().enumerate() {
            let [a, b, c] = triangle.map(|corner| self.posed[corner as usize]);
            if triangle_frame(a, b, c).is_none() {
                continue;
            }
            let nearest = closest_point_on_triangle(point, a, b, c);
            let distance = nearest.distance_squared(point);
            if best.is_none_or(|(least, ..)| distance < least) {
                best = Some((distance, index as u32, barycentric(nearest, a, b, c)));
            }
        }
        best.map(|(_, triangle, weights)| (triangle, weights))
    }
}

/// The orthonormal frame of the triangle `a`, `b`, `c`: its first edge, the second axis in its plane, its
/// normal (right-handed, by the corners' order); `None` for a triangle without area.
fn triangle_frame(a: DVec3, b: DVec3, c: DVec3) -> Option<DMat3> {
    let tangent = (b - a).try_normalize()?;
    let normal = (b - a).cross(c - a).try_normalize()?;
    Some(DMat3::from_cols(tangent, normal.cross(tangent), normal))
}

/// Strands whose head has a scalp mesh, what they are bound to, and whether they changed.
type ScalpStrands<'w, 's> = Query<
    'w,
    's,
    (Entity, Ref<'static, HairStrand>, &'static StrandOf, &'static SimulatedStrand, Option<&'static ScalpRootBinding>),
>;

/// Binds the roots of new or changed strands, and of heads given a new scalp, to their nearest scalp
/// triangle, in the scalp's pose now.
fn bind_roots(
    mut commands: Commands,
    meshes: Option<Res<Assets<Mesh>>>,
    scalp_meshes: Query<(&Mesh3d, Has<SkinnedMesh>)>,
    mut heads: Query<(Ref<HairScalpMesh>, &mut ScalpPose)>,
    strands: ScalpStrands,
    mut posed: Local<HashMap<Entity, Option<PosedScalp>>>,
) {
    posed.clear();
    for (entity, spec, &StrandOf(head), strand, binding) in &strands {
        let Ok((scalp, mut pose)) = heads.get_mut(head) else {
            continue;
        };
        let fresh = binding.is_some_and(|binding| binding.mesh == scalp.0) && !spec.is_changed() && !scalp.is_changed();
        if fresh {
            continue;
        }
        let Some(anchor) = strand.root_anchor() else {
            continue;
        };
        let scalp_mesh = scalp.0;
        let posed = posed.entry(head).or_insert_with(|| {
            let (mesh3d, skinned) = scalp_meshes.get(scalp_mesh).ok()?;
            let mesh = meshes.as_ref()?.get(&mesh3d.0)?; // Not loaded yet: tried again next step.
            let read = PosedScalp::new(mesh, skinned, pose.joints.as_deref()?);
            read.map_err(|problem| report(head, &mut pose.mesh_problem, Some(problem))).ok()
        });
        let Some(posed) = posed else {
            continue;
        };
        let Some((triangle, weights)) = posed.nearest(anchor.position) else {
            report(head, &mut pose.mesh_problem, Some(ScalpError::NoTriangle));
            continue;
        };
        let corners = posed.triangles[triangle as usize];
        let [a, b, c] = corners.map(|corner| posed.posed[corner as usize]);
        let Some(frame) = triangle_frame(a, b, c) else {
            continue;
        };
        let to_frame = frame.transpose();
        commands.entity(entity).insert(ScalpRootBinding {
            mesh: scalp_mesh,
            triangle,
            barycentric: weights,
            corners: corners.map(|corner| posed.corners[corner as usize]),
            edge_direction: to_frame * anchor.edge.normalize(),
            material_direction: to_frame * anchor.material_direction,
        });
    }
}

/// Moves every bound root's anchor to its triangle's point as the scalp is posed now, its edge and
/// material direction turned with the triangle's frame.
fn follow_scalps(heads: Query<&ScalpPose>, mut strands: Query<(&ScalpRootBinding, &StrandOf, &mut SimulatedStrand)>) {
    strands.par_iter_mut().for_each(|(binding, &StrandOf(head), mut strand)| {
        let Some(joints) = heads.get(head).ok().and_then(|pose| pose.joints.as_deref()) else {
            return;
        };
        let corners = binding.corners.map(|corner| ScalpPose::skin(joints, &corner));
        let [Some(a), Some(b), Some(c)] = corners else {
            return;
        };
        // A triangle skinned flat keeps the root where it last was.
        let Some(frame) = triangle_frame(a, b, c) else {
            return;
        };
        let weights = binding.barycentric;
        let root = weights.x * a + weights.y * b + weights.z * c;
        strand.move_root_anchor(root, frame * binding.edge_direction, frame * binding.material_direction);
    });
}
