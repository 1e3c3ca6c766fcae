//! Colliders baked from meshes: a face with its ears, shoulders, a body. The mesh is baked once into a
//! signed distance field ([`DistanceField`]) and the collider moves rigidly with its entity, as every
//! [`HairCollider`] does.
//!
//! Two ways in:
//! - [`HairCollider::from_mesh`] bakes a [`Mesh`] you hold, now;
//! - [`HairColliderFromMesh`] beside a [`Mesh3d`] bakes that mesh once its asset is loaded (a glTF's), on
//!   Bevy's async compute pool, and puts the [`HairCollider`] on the entity.
//!
//! ```
//! # use bevy::prelude::*;
//! # use bevy_hair_sim::prelude::*;
//! # let mut meshes = Assets::<Mesh>::default();
//! # let mut world = World::new();
//! # let head = world.spawn(HairHead).id();
//! // The face, baked now at the default resolution (64 cells along its longest side)...
//! let face = Sphere::new(0.1).mesh().ico(4).unwrap();
//! let collider = HairCollider::from_mesh(&face, MeshColliderSettings::default())?;
//! world.spawn((collider, HairColliderOf(head), ChildOf(head)));
//! // ...or the body's own mesh, baked when it has loaded.
//! world.spawn((Mesh3d(meshes.add(Capsule3d::new(0.12, 0.3))), HairColliderFromMesh::default(), HairColliderOf(head)));
//! # Ok::<(), bevy_hair_sim::collision::MeshColliderError>(())
//! ```
//!
//! **Skinned meshes.** A [`Mesh3d`] that is skinned is drawn where its joints put it, not where its
//! entity is, so bake the part that follows one joint into that joint's space and put the collider on
//! the joint: [`MeshColliderSettings::transform`] set to the joint's inverse bind pose
//! (`SkinnedMeshInverseBindposes`). The collider is rigid: it follows the joint, not the skin's bending.
//!
//! **The mesh** must be a triangle list with positions kept in the main world (a glTF mesh is, unless
//! loaded as render-only). It should be closed; a mesh with small holes is baked with the sign that two of
//! three directions agree on, and its open edges are reported as a warning.
//!
//! **Cost.** Baking takes a fraction of a second, off the frame when done by [`HairColliderFromMesh`]:
//! measured (`cargo run --release --example benchmark mesh-collider`), 0.24 s for 2 000 triangles and
//! 0.38 s for 9 680 at the default 64 cells, 1.0–1.7 s at 128; the grid's sweep, which grows with the cube
//! of the resolution, costs more than the triangles. Meeting hair, a mesh costs about seven times a sphere
//! (a 10 cm ball that 1 000 strands lie on: 17 ms a step against 2.5): every edge near it is searched
//! for dipping in between samples half a cell apart. Use a sphere, capsule or box where one fits, and a
//! mesh for what does not (a face, ears). The GPU's follower placement does not push followers out of
//! mesh colliders; the guides, and CPU-placed followers, meet them.

use bevy::math::{Affine3A, DVec3};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::platform::sync::Arc;
use bevy::prelude::*;
use bevy::tasks::{AsyncComputeTaskPool, Task, block_on, poll_once};
use thiserror::Error;

use super::HairCollider;
use crate::rod::{ColliderShape, DistanceField, DistanceFieldError};

/// How a mesh is baked into a collider.
#[derive(Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Debug, Default, Clone, PartialEq)]
pub struct MeshColliderSettings {
    /// Cells of the distance grid along the mesh's longest side (≥ 4). Default 64: 3 mm cells over a
    /// 20 cm head. Features smaller than a cell are rounded off; memory and baking time grow with its
    /// cube.
    pub resolution: u32,
    /// Maps the mesh's positions into the collider entity's local space before baking (identity by
    /// default): a joint's inverse bind pose for a part of a skinned mesh that follows that joint.
    pub transform: Affine3A,
}

impl Default for MeshColliderSettings {
    fn default() -> Self {
        Self { resolution: 64, transform: Affine3A::IDENTITY }
    }
}

/// Why a mesh could not become a collider.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MeshColliderError {
    /// The mesh is not a triangle list.
    #[error("the mesh's topology is {0:?}; a collider is baked from a triangle list")]
    NotTriangles(PrimitiveTopology),
    /// The mesh has no `f32 × 3` positions in the main world.
    #[error(
        "the mesh has no positions in the main world (missing, not Float32x3, or extracted to the render world only: keep it with RenderAssetUsages::MAIN_WORLD)"
    )]
    NoPositions,
    /// The index count is not a multiple of three.
    #[error("the mesh has {0} indices, not a whole number of triangles")]
    PartialTriangle(usize),
    /// The resolution is below 4 cells.
    #[error("a resolution of {0} cells is too coarse; use at least 4")]
    ResolutionTooLow(u32),
    /// The mesh's positions span no volume.
    #[error("the mesh spans no length along any axis")]
    NoExtent,
    /// The mesh's data is unusable.
    #[error(transparent)]
    Field(#[from] DistanceFieldError),
}

impl HairCollider {
    /// A collider baked from `mesh` (a closed triangle mesh, m, in the collider entity's local space
    /// after `settings.transform`), with the default friction. See the [module documentation](self).
    pub fn from_mesh(mesh: &Mesh, settings: MeshColliderSettings) -> Result<Self, MeshColliderError> {
        let (positions, triangles) = mesh_triangles(mesh, settings.transform)?;
        let field = bake(&positions, &triangles, settings.resolution)?;
        Ok(Self::new(ColliderShape::mesh(Arc::new(field))))
    }
}

/// The positions (m, through `transform`) and triangles of a triangle-list `mesh`.
pub fn mesh_triangles(mesh: &Mesh, transform: Affine3A) -> Result<(Vec<DVec3>, Vec<[u32; 3]>), MeshColliderError> {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Err(MeshColliderError::NotTriangles(mesh.primitive_topology()));
    }
    let Ok(VertexAttributeValues::Float32x3(positions)) = mesh.try_attribute(Mesh::ATTRIBUTE_POSITION) else {
        return Err(MeshColliderError::NoPositions);
    };
    let positions: Vec<DVec3> =
        positions.iter().map(|&position| transform.transform_point3(Vec3::from(position)).as_dvec3()).collect();
    let indices: Vec<u32> = match mesh.try_indices_option().ok().flatten() {
        Some(Indices::U16(indices)) => indices.iter().map(|&index| u32::from(index)).collect(),
        Some(Indices::U32(indices)) => indices.clone(),
        None => (0..positions.len() as u32).collect(),
    };
    if !indices.len().is_multiple_of(3) {
        return Err(MeshColliderError::PartialTriangle(indices.len()));
    }
    let triangles = indices.chunks_exact(3).map(|triangle| [triangle[0], triangle[1], triangle[2]]).collect();
    Ok((positions, triangles))
}

/// Bakes triangles with `resolution` cells along their longest side.
fn bake(positions: &[DVec3], triangles: &[[u32; 3]], resolution: u32) -> Result<DistanceField, MeshColliderError> {
    if resolution < 4 {
        return Err(MeshColliderError::ResolutionTooLow(resolution));
    }
    let used = triangles.iter().flatten().filter_map(|&vertex| positions.get(vertex as usize));
    let (low, high) = used
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(low, high), &position| (low.min(position), high.max(position)));
    let longest = (high - low).max_element();
    if triangles.is_empty() {
        return Err(DistanceFieldError::NoTriangles.into());
    }
    if longest.is_finite() && longest <= 0.0 {
        return Err(MeshColliderError::NoExtent);
    }
    // A non-finite extent is reported by the baking, with the vertex.
    let cell = if longest.is_finite() { longest / f64::from(resolution) } else { 1.0 };
    let field = DistanceField::bake(positions, triangles, cell)?;
    Ok(field)
}

/// Bakes the entity's [`Mesh3d`] into its [`HairCollider`] once the mesh has loaded (see the [module
/// documentation](self)). Changing this component or the [`Mesh3d`] bakes again (the collider is removed
/// meanwhile); a mesh asset edited in place is not baked again.
#[derive(Component, Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Component, Debug, Default, Clone, PartialEq)]
pub struct HairColliderFromMesh {
    /// How the mesh is baked.
    pub settings: MeshColliderSettings,
    /// Coulomb friction coefficient of the collider, dimensionless (see [`HairCollider::friction`]).
    pub friction: f32,
}

impl Default for HairColliderFromMesh {
    fn default() -> Self {
        Self { settings: MeshColliderSettings::default(), friction: HairCollider::DEFAULT_FRICTION }
    }
}

/// Where an entity's [`HairColliderFromMesh`] stands.
#[derive(Component, Debug)]
pub enum MeshColliderBaking {
    /// Baking on the async compute pool.
    Baking(Task<Result<HairCollider, MeshColliderError>>),
    /// Baked: the [`HairCollider`] is on the entity.
    Baked,
    /// The mesh could not be baked (reported once); changing [`HairColliderFromMesh`] or [`Mesh3d`] tries
    /// again.
    Failed(MeshColliderError),
}

/// Entities asking for a mesh collider: their request, mesh, and whether a bake was started.
type MeshColliderRequests<'w, 's> =
    Query<'w, 's, (Entity, Ref<'static, HairColliderFromMesh>, Ref<'static, Mesh3d>, Has<MeshColliderBaking>)>;

/// Starts baking meshes whose [`HairColliderFromMesh`] or [`Mesh3d`] is new or changed.
pub(crate) fn start_mesh_bakes(
    mut commands: Commands,
    meshes: Option<Res<Assets<Mesh>>>,
    colliders: MeshColliderRequests,
) {
    let Some(meshes) = meshes else {
        return; // No mesh assets in this app: nothing can load.
    };
    for (entity, from_mesh, mesh3d, seen) in &colliders {
        let asked_again = from_mesh.is_changed() || mesh3d.is_changed();
        if seen && !asked_again {
            continue;
        }
        let Some(mesh) = meshes.get(&mesh3d.0) else {
            continue; // Not loaded yet: tried again next frame.
        };
        let (settings, friction) = (from_mesh.settings, from_mesh.friction);
        let triangles = mesh_triangles(mesh, settings.transform);
        let task = AsyncComputeTaskPool::get().spawn(async move {
            let (positions, triangles) = triangles?;
            let field = bake(&positions, &triangles, settings.resolution)?;
            Ok(HairCollider::new(ColliderShape::mesh(Arc::new(field))).with_friction(friction))
        });
        commands.entity(entity).remove::<HairCollider>().insert(MeshColliderBaking::Baking(task));
    }
}

/// Puts finished bakes' colliders on their entities, reporting failures and open meshes once.
pub(crate) fn finish_mesh_bakes(mut commands: Commands, mut bakes: Query<(Entity, &mut MeshColliderBaking)>) {
    for (entity, mut baking) in &mut bakes {
        let MeshColliderBaking::Baking(task) = &mut *baking else {
            continue;
        };
        let Some(result) = block_on(poll_once(task)) else {
            continue;
        };
        match result {
            Ok(collider) => {
                if let ColliderShape::Mesh { field, .. } = &collider.shape
                    && field.open_edges() > 0
                {
                    warn!(
                        "hair collider {entity}: its mesh is not closed ({} open edges); inside is where two of three directions agree",
                        field.open_edges()
                    );
                }
                commands.entity(entity).insert(collider);
                *baking = MeshColliderBaking::Baked;
            }
            Err(error) => {
                error!("hair collider {entity} could not be baked from its mesh: {error}");
                *baking = MeshColliderBaking::Failed(error);
            }
        }
    }
}
