//! A game that glob-imports this crate's prelude beside a physics engine's must be able to name every
//! item of both. Two glob imports that export one name make it ambiguous (an error where it is used), so
//! this file compiles only while no name of ours clashes. The stand-ins below export items named like
//! those of avian's prelude (avian3d 0.4–0.7) and bevy_rapier3d's (0.28–0.32), and this test uses each.

#![allow(dead_code)]

/// Items named like avian's and bevy_rapier's preludes. Stand-ins: bevy_rapier3d is not among this crate's
/// dependencies, and avian3d, which builds (the `avian` feature, `tests/avian_colliders.rs`), would be built
/// for every plain `cargo test` if this file imported it.
mod physics_prelude {
    macro_rules! stand_ins {
        ($($name:ident),* $(,)?) => { $(#[derive(Debug, Default)] pub struct $name;)* };
    }
    stand_ins!(
        // avian
        AngularVelocity,
        Collider,
        ColliderAabb,
        ColliderConstructor,
        ColliderDensity,
        ColliderOf,
        ColliderTransform,
        CollidingEntities,
        CollisionEventsEnabled,
        CollisionLayers,
        CollisionStart,
        Friction,
        Gravity,
        LinearDamping,
        LinearVelocity,
        Mass,
        PhysicsDebugPlugin,
        PhysicsPlugins,
        PhysicsSchedule,
        PhysicsSystems,
        Position,
        Restitution,
        RigidBody,
        RigidBodyColliders,
        Rotation,
        Sensor,
        SpatialQuery,
        Forces,
        // bevy_rapier
        ActiveEvents,
        Ccd,
        ColliderMassProperties,
        CollisionEvent,
        CollisionGroups,
        Damping,
        ExternalForce,
        ExternalImpulse,
        GravityScale,
        LockedAxes,
        RapierConfiguration,
        RapierContext,
        RapierDebugRenderPlugin,
        RapierPhysicsPlugin,
        Velocity,
        NoUserData,
    );
}

use bevy::prelude::*;
use bevy_hair_sim::prelude::*;
use physics_prelude::*;

#[test]
fn every_name_of_both_preludes_can_be_used() {
    let theirs = format!(
        "{:?}",
        (
            (AngularVelocity, Collider, ColliderAabb, ColliderConstructor, ColliderDensity, ColliderOf),
            (ColliderTransform, CollidingEntities, CollisionEventsEnabled, CollisionLayers, CollisionStart),
            (Friction, Gravity, LinearDamping, LinearVelocity, Mass, PhysicsDebugPlugin, PhysicsPlugins),
            (PhysicsSchedule, PhysicsSystems, Position, Restitution, RigidBody, RigidBodyColliders, Rotation),
            (Sensor, SpatialQuery, Forces),
            (ActiveEvents, Ccd, ColliderMassProperties, CollisionEvent, CollisionGroups, Damping),
            (ExternalForce, ExternalImpulse, GravityScale, LockedAxes, RapierConfiguration, RapierContext),
            (RapierDebugRenderPlugin, RapierPhysicsPlugin, Velocity, NoUserData),
        )
    );
    assert!(theirs.contains("ColliderOf") && theirs.contains("RigidBody"));

    // Ours, beside them, in one app.
    let mut app = App::new();
    hair_sim_support::logs::share_with(&mut app);
    app.add_plugins((MinimalPlugins, HairPlugins::default()));
    let head = app.world_mut().spawn((HairHead, Transform::default())).id();
    let collider = app.world_mut().spawn((HairCollider::sphere(0.1), HairColliderOf(head), Transform::default())).id();
    let strand = app.world_mut().spawn((HairStrand::straight(Vec3::Y * 0.1, Vec3::Y, 0.1, 8), StrandOf(head))).id();
    app.update();
    app.update();
    assert_eq!(app.world().get::<HeadColliders>(head).map(|c| c.colliders().to_vec()), Some(vec![collider]));
    assert!(app.world().get::<StrandNodes>(strand).is_some());
}
