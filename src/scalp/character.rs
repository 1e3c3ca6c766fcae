//! Hair put on a character by the names in its scene: [`HairOnCharacter`].

use bevy::math::Affine3A;
use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy::transform::helper::TransformHelper;

use super::{HairScalpMesh, ScalpWhereHeadSkins, joint_weights};
use crate::collision::{HairColliderFromMesh, HairColliderOf, MeshColliderSettings};
use crate::groom::{GroomFrame, HairGroom, HairGroomFile, HeadAxes};
use crate::simulation::HairHead;

/// Puts hair on a character by the names of its head joint, scalp mesh and collider meshes.
///
/// Put it on the scene's root entity (a glTF's `WorldAssetRoot`, or entities of your own); the search
/// starts once the scene has spawned. Among the root's descendants, the entity named
/// [`head_joint`](Self::head_joint) becomes the [`HairHead`], bound to the scalp mesh named
/// [`scalp_mesh`](Self::scalp_mesh) ([`HairScalpMesh`]) and given the [`hair`](Self::hair); each mesh
/// named in [`collider_meshes`](Self::collider_meshes) is baked into a collider of that head
/// ([`HairColliderFromMesh`]). A mesh's name may be that of its entity, of a node above it (a glTF
/// node's primitives are its children), or the glTF mesh's own name (Bevy names each primitive's entity
/// `<mesh name>.<material name>`; the first primitive is taken). Until every name is found, the search is
/// tried again each frame; [`HairOnCharacterStatus`] says how it stands.
///
/// A rig's head joint has axes of its own: a procedural groom turns onto them, read off the rig's bind pose
/// by glTF's convention that a model stands `+Y` up and faces `+Z`
/// ([`HairOnCharacter::with_gltf_head_axes`]), or given by hand ([`HairOnCharacter::with_head_axes`]). The
/// groom's lengths are metres whatever the character's scale (a character modelled in centimetres and spawned
/// at 0.01 wears the same hair as one modelled in metres).
///
/// A skinned collider mesh is baked in the head joint's space (through the joint's inverse bind pose)
/// and follows that joint rigidly: a face and ears do; a body that bends away from the head is better
/// held by capsules on its own joints.
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_hair_sim::prelude::*;
/// # fn spawn(mut commands: Commands, assets: Res<AssetServer>) {
/// commands.spawn((
///     WorldAssetRoot(assets.load(GltfAssetLabel::Scene(0).from_asset("character.glb"))),
///     Transform::from_scale(Vec3::splat(0.01)), // modelled in centimetres
///     HairOnCharacter::new("Head", CharacterHair::Groom(HairGroom::default()))
///         .with_gltf_head_axes() // the joint's face and crown from its bind pose
///         .with_scalp_mesh("Scalp")
///         .with_collider_meshes(["Face"]),
/// ));
/// # }
/// ```
///
/// `examples/gltf_character.rs` puts hair on the crate's glTF mannequin this way (`assets/models/Mannequin.glb`).
#[derive(Component, Reflect, Debug, Clone, PartialEq)]
#[reflect(Component, Debug, Clone, PartialEq)]
pub struct HairOnCharacter {
    /// `Name` of the joint the hair grows on (the head bone): its local space is the hair's.
    pub head_joint: String,
    /// `Name` of the scalp mesh the roots are bound to; `None`: the roots follow the joint.
    pub scalp_mesh: Option<String>,
    /// `Name`s of meshes baked into colliders for this hair (a face, ears).
    pub collider_meshes: Vec<String>,
    /// The hair put on the joint.
    pub hair: CharacterHair,
    /// Whether a procedural groom's [`Scalp`](crate::groom::Scalp) ellipsoid is fitted to the head's skinned
    /// vertices (those the head joint weighs at least half) before it grows ([`Scalp::fitted_to`]), its
    /// hairline kept: the skull found on the rig, not measured by hand. Default `false`: the groom's own.
    ///
    /// [`Scalp::fitted_to`]: crate::groom::Scalp::fitted_to
    pub fit_scalp: bool,
    /// Whether the scalp mesh grows hair where the head joint skins it ([`ScalpWhereHeadSkins`]) rather than
    /// by its painted density: for a character that is one skinned mesh. Default `false`.
    pub scalp_where_head_skins: bool,
    /// Whether a procedural groom's [`HeadAxes`] are read off the head joint's bind pose (its inverse bind
    /// matrix in a skin of the character's): the face along the model's `+Z` and the crown along its `+Y`,
    /// glTF's convention for how a model stands (`HairOnCharacter::with_gltf_head_axes`). Default
    /// `false`: the groom's own axes. A model made facing another way (Bevy's `−Z`, as a character built in
    /// code may be) gives its axes by hand instead ([`HairOnCharacter::with_head_axes`]).
    pub gltf_head_axes: bool,
}

/// The hair [`HairOnCharacter`] puts on a character's head joint.
#[derive(Reflect, Debug, Clone, PartialEq)]
#[reflect(Debug, Clone, PartialEq)]
pub enum CharacterHair {
    /// A procedural groom, in the joint's space.
    Groom(HairGroom),
    /// A groom file, placed in the joint's space.
    File(HairGroomFile),
    /// None: strands of your own, spawned on the head once it is there.
    Nothing,
}

/// How a [`HairOnCharacter`] stands; on its entity.
#[derive(Component, Reflect, Debug, Clone, PartialEq, Eq)]
#[reflect(Component, Debug, Clone, PartialEq)]
pub enum HairOnCharacterStatus {
    /// Some names are not among the descendants yet (the scene may still be loading).
    Waiting {
        /// The names not found.
        missing: Vec<String>,
        /// Frames waited so far.
        frames: u32,
    },
    /// The hair is on this head joint.
    Attached {
        /// The head joint, now a [`HairHead`].
        head: Entity,
    },
}

impl HairOnCharacter {
    /// Hair `hair` on the joint named `head_joint`, following the joint, with no colliders.
    pub fn new(head_joint: impl Into<String>, hair: CharacterHair) -> Self {
        Self {
            head_joint: head_joint.into(),
            scalp_mesh: None,
            collider_meshes: Vec::new(),
            hair,
            fit_scalp: false,
            scalp_where_head_skins: false,
            gltf_head_axes: false,
        }
    }

    /// The roots bound to the mesh named `name`.
    pub fn with_scalp_mesh(mut self, name: impl Into<String>) -> Self {
        self.scalp_mesh = Some(name.into());
        self
    }

    /// The head joint's own axes: its face looks along `forward` and its crown along `up`, in the joint's
    /// local space ([`HeadAxes`]); a procedural groom turns onto them (a groom file is turned by its
    /// [`GroomPlacement`](crate::groom::GroomPlacement)'s transform).
    pub fn with_head_axes(mut self, forward: Vec3, up: Vec3) -> Self {
        if let CharacterHair::Groom(groom) = &mut self.hair {
            groom.head_axes = HeadAxes::new(forward, up);
        }
        self
    }

    /// The head joint's axes read off its bind pose by glTF's convention, the model standing `+Y` up and
    /// facing `+Z` ([`HairOnCharacter::gltf_head_axes`]): no numbers to find for a glTF character.
    pub fn with_gltf_head_axes(mut self) -> Self {
        self.gltf_head_axes = true;
        self
    }

    /// Hair grown on the mesh named `name` where the head joint skins it (its weight for the head as the
    /// density; [`ScalpWhereHeadSkins`]), its roots bound to it: the head's own triangles as its scalp, on
    /// a character that is one skinned mesh with no painted density.
    pub fn with_scalp_where_head_skins(mut self, name: impl Into<String>) -> Self {
        self.scalp_mesh = Some(name.into());
        self.scalp_where_head_skins = true;
        self
    }

    /// A procedural groom's skull ellipsoid fitted to the head's skinned vertices
    /// ([`HairOnCharacter::fit_scalp`]).
    pub fn with_scalp_fitted_to_head(mut self) -> Self {
        self.fit_scalp = true;
        self
    }

    /// Colliders baked from the meshes of these names.
    pub fn with_collider_meshes(mut self, names: impl IntoIterator<Item = impl Into<String>>) -> Self {
        self.collider_meshes = names.into_iter().map(Into::into).collect();
        self
    }
}

/// Frames a [`HairOnCharacter`] waits before saying which names it has not found.
const FRAMES_BEFORE_WARNING: u32 = 600;

/// Attaches waiting [`HairOnCharacter`]s whose names are all found.
#[allow(clippy::too_many_arguments)]
pub(crate) fn attach_hair_to_characters(
    mut commands: Commands,
    mut characters: Query<(Entity, &HairOnCharacter, Option<&mut HairOnCharacterStatus>)>,
    children: Query<&Children>,
    names: Query<&Name>,
    meshes: Query<(&Mesh3d, Option<&SkinnedMesh>)>,
    bindposes: Option<Res<Assets<SkinnedMeshInverseBindposes>>>,
    mesh_assets: Option<Res<Assets<Mesh>>>,
    transforms: TransformHelper,
) {
    for (root, character, status) in &mut characters {
        if matches!(status.as_deref(), Some(HairOnCharacterStatus::Attached { .. })) {
            continue;
        }
        let named = |wanted: &str| {
            children.iter_descendants(root).find(|&entity| names.get(entity).is_ok_and(|name| name.as_str() == wanted))
        };
        // The entity named, or its first descendant, with a mesh; else the first primitive of the glTF mesh
        // of that name (Bevy names a glTF primitive's entity `<mesh name>.<material name>`).
        let mesh_named = |wanted: &str| {
            let in_node = named(wanted).and_then(|entity| {
                std::iter::once(entity).chain(children.iter_descendants(entity)).find(|&entity| meshes.contains(entity))
            });
            in_node.or_else(|| {
                children.iter_descendants(root).find(|&entity| {
                    meshes.contains(entity)
                        && names.get(entity).is_ok_and(|name| {
                            name.as_str().strip_prefix(wanted).is_some_and(|rest| rest.starts_with('.'))
                        })
                })
            })
        };
        let head = named(&character.head_joint);
        let scalp = character.scalp_mesh.as_deref().map(|name| (name, mesh_named(name)));
        let colliders: Vec<(&str, Option<Entity>)> =
            character.collider_meshes.iter().map(|name| (name.as_str(), mesh_named(name))).collect();
        let mut missing: Vec<String> = std::iter::once((character.head_joint.as_str(), head))
            .chain(scalp)
            .chain(colliders.iter().copied())
            .filter(|(_, found)| found.is_none())
            .map(|(name, _)| name.to_owned())
            .collect();
        let skins = || {
            children.iter_descendants(root).filter_map(|entity| match meshes.get(entity) {
                Ok((mesh, Some(skin))) => Some((mesh, skin)),
                _ => None,
            })
        };
        let groom = matches!(character.hair, CharacterHair::Groom(_));
        // The head joint's axes from its bind pose, once a skin's bind poses have loaded.
        let axes = head.filter(|_| groom && character.gltf_head_axes).and_then(|head| {
            let axes = skins().find_map(|(_, skin)| bind_pose_axes(head, skin, bindposes.as_deref()?));
            if axes.is_none() {
                missing.push(format!("{} (its bind pose, loading)", character.head_joint));
            }
            axes
        });
        // The head's skinned vertices, to fit the skull to, once their meshes have loaded.
        let fit_to = head.filter(|_| groom && character.fit_scalp).and_then(|head| {
            let vertices = head_vertices(head, skins(), mesh_assets.as_deref(), bindposes.as_deref());
            if vertices.is_none() {
                missing.push(format!("{} (its skinned meshes, loading)", character.head_joint));
            }
            vertices
        });
        let Some(head) = head.filter(|_| missing.is_empty()) else {
            let frames = match status.as_deref() {
                Some(HairOnCharacterStatus::Waiting { frames, .. }) => frames + 1,
                _ => 1,
            };
            if frames == FRAMES_BEFORE_WARNING {
                warn!("hair on character {root}: no descendant named {missing:?} after {FRAMES_BEFORE_WARNING} frames");
            }
            let waiting = HairOnCharacterStatus::Waiting { missing, frames };
            match status {
                Some(mut status) => *status = waiting,
                None => {
                    commands.entity(root).insert(waiting);
                }
            }
            continue;
        };
        let mut hair = character.hair.clone();
        if let (Some(axes), CharacterHair::Groom(groom)) = (axes, &mut hair) {
            info!(
                "hair on character {root}: the head joint faces {} and its crown is {} (its bind pose, glTF's +Z front and +Y up)",
                axes.forward, axes.up
            );
            groom.head_axes = axes;
        }
        if let (Some(vertices), CharacterHair::Groom(groom)) = (fit_to, &mut hair) {
            // In metres along the groom's axes (the joint's scale as it is now, propagated or not).
            let frame = GroomFrame {
                rotation: groom.head_axes.rotation().unwrap_or(Quat::IDENTITY),
                scale: GroomFrame::head_scale(head, &transforms).0,
            };
            let points: Vec<Vec3> = vertices.iter().map(|&vertex| frame.point_in_frame(vertex)).collect();
            match groom.scalp.fitted_to(&points) {
                Ok(fitted) => {
                    info!(
                        "hair on character {root}: the skull fitted to {} head vertices: centre {} m, semi-axes {} m",
                        points.len(),
                        fitted.centre,
                        fitted.semi_axes
                    );
                    groom.scalp = fitted;
                }
                Err(error) => error!("hair on character {root}: its groom keeps its own scalp, as {error}"),
            }
        }
        let mut joint = commands.entity(head);
        joint.insert(HairHead);
        if let Some((_, Some(scalp))) = scalp {
            joint.insert(HairScalpMesh(scalp));
            if character.scalp_where_head_skins {
                joint.insert(ScalpWhereHeadSkins);
            }
        }
        match &hair {
            CharacterHair::Groom(groom) => {
                joint.insert(groom.clone());
            }
            CharacterHair::File(file) => {
                joint.insert(file.clone());
            }
            CharacterHair::Nothing => {}
        }
        for (name, mesh) in colliders {
            let Some((mesh, (mesh3d, skin))) = mesh.and_then(|mesh| Some((mesh, meshes.get(mesh).ok()?))) else {
                continue;
            };
            // A skinned mesh is baked in the head joint's space; one without a skin moves with its entity.
            let Some(skin) = skin else {
                commands.entity(mesh).insert((HairColliderFromMesh::default(), HairColliderOf(head)));
                continue;
            };
            let bindpose = skin.joints.iter().position(|&joint| joint == head).and_then(|index| {
                bindposes
                    .as_ref()
                    .and_then(|assets| assets.get(&skin.inverse_bindposes))
                    .and_then(|poses| poses.get(index))
            });
            let Some(bindpose) = bindpose else {
                warn!(
                    "hair on character {root}: collider mesh {name:?} is skinned, but not to the head joint; left out"
                );
                continue;
            };
            let settings = MeshColliderSettings { transform: Affine3A::from_mat4(*bindpose), ..default() };
            commands.spawn((
                Mesh3d(mesh3d.0.clone()),
                HairColliderFromMesh { settings, ..default() },
                HairColliderOf(head),
                ChildOf(head),
                Visibility::Hidden,
            ));
        }
        commands.entity(root).insert(HairOnCharacterStatus::Attached { head });
    }
}

/// The joint `head`'s axes in `skin`'s bind pose: the model's `+Z` (glTF's front) and `+Y` (its up) in the
/// joint's local space, through the joint's inverse bind matrix; `None` if the skin does not have the
/// joint, or its matrix is degenerate.
fn bind_pose_axes(
    head: Entity,
    skin: &SkinnedMesh,
    bindposes: &Assets<SkinnedMeshInverseBindposes>,
) -> Option<HeadAxes> {
    let index = skin.joints.iter().position(|&joint| joint == head)?;
    let to_joint = bindposes.get(&skin.inverse_bindposes)?.get(index)?;
    let forward = to_joint.transform_vector3(Vec3::Z).try_normalize()?;
    let up = to_joint.transform_vector3(Vec3::Y).try_normalize()?;
    let axes = HeadAxes::new(forward, up);
    axes.rotation().is_ok().then_some(axes)
}

/// The vertices of the skinned meshes `skins` that the joint `head` weighs at least half, in the joint's
/// local space (through its inverse bind pose); `None` while a mesh or its bind poses have not loaded.
fn head_vertices<'a>(
    head: Entity,
    skins: impl Iterator<Item = (&'a Mesh3d, &'a SkinnedMesh)>,
    meshes: Option<&Assets<Mesh>>,
    bindposes: Option<&Assets<SkinnedMeshInverseBindposes>>,
) -> Option<Vec<Vec3>> {
    let mut vertices = Vec::new();
    for (mesh, skin) in skins {
        let Some(joint) = skin.joints.iter().position(|&joint| joint == head) else { continue };
        let mesh = meshes?.get(&mesh.0)?;
        let to_joint = *bindposes?.get(&skin.inverse_bindposes)?.get(joint)?;
        let (Some(VertexAttributeValues::Float32x3(positions)), Some(weights)) =
            (mesh.attribute(Mesh::ATTRIBUTE_POSITION), joint_weights(mesh, skin, head))
        else {
            continue;
        };
        let on_head = positions.iter().zip(weights).filter(|(_, weight)| *weight >= 0.5);
        vertices.extend(on_head.map(|(position, _)| to_joint.transform_point3(Vec3::from_array(*position))));
    }
    Some(vertices)
}
