//! What Bevy's own tools see of the hair: its statistics in the `DiagnosticsStore`, and the components a
//! game authors in its type registry (so that a scene file or an editor can write them).

use std::any::TypeId;

use bevy::diagnostic::{DiagnosticPath, DiagnosticsStore};
use bevy::prelude::*;
use bevy::reflect::ReflectFromReflect;
use bevy_hair_sim::debug::HairDiagnostics;
use bevy_hair_sim::prelude::*;
use hair_sim_support::headless::{hair_app_with, spawn_head};

#[test]
fn the_hair_s_statistics_are_in_bevy_s_diagnostics_store() {
    let mut app = hair_app_with(HairDiagnosticsPlugin);
    spawn_head(&mut app, Transform::from_xyz(0.0, 1.6, 0.0), 12, 8);
    for _ in 0..5 {
        app.update();
    }
    let statistics = app.world().resource::<HairStatistics>().clone();
    let store = app.world().resource::<DiagnosticsStore>();
    let latest = |path: DiagnosticPath| store.get_measurement(&path).map(|measurement| measurement.value);
    assert_eq!(statistics.strands, 12);
    assert_eq!(latest(HairDiagnostics::STRANDS), Some(12.0));
    assert_eq!(latest(HairDiagnostics::FAULTS), Some(0.0));
    assert_eq!(latest(HairDiagnostics::STRANDS_ON_GPU), Some(0.0));
    assert_eq!(latest(HairDiagnostics::NEWTON_ITERATIONS), Some(statistics.mean_newton_iterations));
    assert_eq!(latest(HairDiagnostics::STEP_TIME), Some(statistics.step_seconds * 1e3));
    assert_eq!(latest(HairDiagnostics::UPDATE_TIME), Some(statistics.update_seconds * 1e3));
    assert!(statistics.update_seconds > 0.0 && statistics.step_seconds > 0.0);
    assert_eq!(store.get(&HairDiagnostics::UPDATE_TIME).unwrap().suffix, "ms");
}

#[test]
fn the_components_a_game_authors_are_reflected_and_registered() {
    let app = hair_app_with(());
    let registry = app.world().resource::<AppTypeRegistry>().read();
    let components = [
        ("HairOnCharacter", TypeId::of::<HairOnCharacter>()),
        ("HairOnCharacterStatus", TypeId::of::<HairOnCharacterStatus>()),
        ("HairGroom", TypeId::of::<HairGroom>()),
        ("HairGroomFile", TypeId::of::<HairGroomFile>()),
        ("StrandColors", TypeId::of::<StrandColors>()),
        ("StrandWidths", TypeId::of::<StrandWidths>()),
    ];
    for (name, id) in components {
        let registration = registry.get(id).unwrap_or_else(|| panic!("{name} is not registered"));
        assert!(registration.data::<ReflectComponent>().is_some(), "{name} cannot be inserted by reflection");
    }
    // A character's hair, as a scene file would write it, made again from its reflection.
    let character = HairOnCharacter::new("b_Head_05", CharacterHair::Groom(HairGroom::default()))
        .with_head_axes(Vec3::X, Vec3::Y)
        .with_collider_meshes(["Face"]);
    let reflected = character.reflect_clone().expect("a reflected clone");
    let from_reflect = registry
        .get_type_data::<ReflectFromReflect>(TypeId::of::<HairOnCharacter>())
        .expect("HairOnCharacter made from its reflection");
    let rebuilt = from_reflect.from_reflect(reflected.as_partial_reflect()).unwrap();
    assert_eq!(rebuilt.downcast_ref::<HairOnCharacter>(), Some(&character));
}
