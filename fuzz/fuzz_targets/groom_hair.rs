//! `GroomFile::from_hair` on arbitrary bytes, then everything a game does with what it accepts.
#![no_main]

use bevy_hair_sim::groom::GroomFile;
use libfuzzer_sys::fuzz_target;

#[path = "../common.rs"]
mod common;

fuzz_target!(|bytes: &[u8]| {
    if let Ok(groom) = GroomFile::from_hair(bytes) {
        common::check_groom(&groom, bytes.len());
    }
});
