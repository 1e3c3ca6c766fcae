//! The contact slots the step reads: the colliders each head's strands meet this step
//! ([`HeadColliderSet`]) and those free strands meet ([`SharedColliderSet`]). The core owns them, as it owns
//! [`StrandForces`](super::StrandForces); [`crate::collision`] fills them.

use bevy::ecs::system::SystemParam;
use bevy::prelude::*;

use super::head::StrandOf;
use crate::rod::MovingCollider;

/// The colliders a head's strands meet this step (its own, shared and included ones, less the
/// excluded), gathered by the plugin into memory reused from step to step.
#[derive(Component, Debug, Clone, Default, PartialEq)]
pub struct HeadColliderSet {
    colliders: Vec<MovingCollider>,
    entities: Vec<Entity>,
    /// Whether a collider of the head is still being made (a mesh collider's mesh loading or baking).
    waiting: bool,
}

impl HeadColliderSet {
    /// The colliders, with their poses at the last step and at this one.
    pub fn colliders(&self) -> &[MovingCollider] {
        &self.colliders
    }

    /// The collider entities, in the same order.
    pub fn entities(&self) -> &[Entity] {
        &self.entities
    }

    /// Whether a collider of the head is still being made (a mesh collider whose mesh is loading or
    /// baking): its strands' gravity preloads, which rest hair on the colliders, wait for it.
    pub fn waiting(&self) -> bool {
        self.waiting
    }

    pub(crate) fn set_waiting(&mut self, waiting: bool) {
        self.waiting = waiting;
    }

    pub(crate) fn clear(&mut self) {
        self.colliders.clear();
        self.entities.clear();
        self.waiting = false;
    }

    /// Adds `entity`'s collider if it is in use and not in the set yet.
    pub(crate) fn add(&mut self, entity: Entity, collider: Option<&MovingCollider>) {
        if let Some(collider) = collider
            && !self.entities.contains(&entity)
        {
            self.colliders.push(collider.clone());
            self.entities.push(entity);
        }
    }
}

/// The colliders that strands with no head meet: the shared ones.
#[derive(Resource, Debug, Clone, Default, PartialEq)]
pub struct SharedColliderSet(pub(crate) HeadColliderSet);

impl SharedColliderSet {
    /// The colliders, with their poses at the last step and at this one.
    pub fn colliders(&self) -> &[MovingCollider] {
        self.0.colliders()
    }
}

/// The colliders each strand meets this step, for the strands' step.
#[derive(SystemParam)]
pub(crate) struct StrandColliders<'w, 's> {
    head_sets: Query<'w, 's, &'static HeadColliderSet>,
    shared: Option<Res<'w, SharedColliderSet>>,
}

impl StrandColliders<'_, '_> {
    /// The colliders of a strand rooted on `strand_of` (the shared ones for a strand with no head; none
    /// without [`HairCollisionPlugin`](crate::collision::HairCollisionPlugin)).
    pub(crate) fn of(&self, strand_of: Option<&StrandOf>) -> &[MovingCollider] {
        match strand_of {
            Some(&StrandOf(head)) => self.head_sets.get(head).map(HeadColliderSet::colliders).unwrap_or_default(),
            None => self.shared.as_deref().map(SharedColliderSet::colliders).unwrap_or_default(),
        }
    }

    /// Whether a collider of the head of a strand rooted on `strand_of` is still being made.
    pub(crate) fn waiting(&self, strand_of: Option<&StrandOf>) -> bool {
        strand_of.is_some_and(|&StrandOf(head)| self.head_sets.get(head).is_ok_and(HeadColliderSet::waiting))
    }
}
