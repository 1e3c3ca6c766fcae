//! A headless look at the mechanics core, until the rendered example scene lands: three strands of
//! real human hair clamped at their roots — a long one that falls and hangs, a short one that sticks
//! out, and a curl that keeps its curl — printed as a table of tip positions while they settle, then
//! while the "head" is shaken.
//!
//! Run with `cargo run --release --example hanging_hair`.

use bevy::math::{DQuat, DVec2, DVec3};
use bevy_hair_sim::rod::{Rod, RodError, RodMaterial, RodWorkspace, StepParams};
use std::f64::consts::PI;

/// A strand growing sideways (+X) from a root 10 cm from the head's centre, `edges` edges long.
fn strand(length: f64, edges: usize) -> Result<Rod, RodError> {
    let nodes: Vec<DVec3> = (0..=edges).map(|i| DVec3::new(0.1 + length * i as f64 / edges as f64, 0.0, 0.0)).collect();
    let mut rod = Rod::new(&nodes, DVec3::Y, RodMaterial::human_hair())?;
    rod.clamp_root_in_place();
    Ok(rod)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut long = strand(0.25, 32)?;
    let mut short = strand(0.03, 16)?;
    let mut curl = strand(0.2, 48)?;
    // Natural curvature of a 1 cm-radius curl, bending towards the strand's m1 (+Y).
    curl.set_natural_curvature(DVec2::new(100.0, 0.0))?;
    let params = StepParams::default();
    let mut workspace = RodWorkspace::default();
    let mut strands = [("long 25 cm", &mut long), ("short 3 cm", &mut short), ("curl 20 cm", &mut curl)];
    let anchors: Vec<[DVec3; 2]> = strands.iter().map(|(_, rod)| [rod.positions()[0], rod.positions()[1]]).collect();

    println!("time   head      {:>28} {:>28} {:>28}", strands[0].0, strands[1].0, strands[2].0);
    for step in 0..=240usize {
        let time = step as f64 * params.dt;
        // Still for two seconds, then shaken 5 cm at 2 Hz and turned back and forth.
        let shaking = time > 2.0;
        let (turn, shift) = if shaking {
            let phase = 2.0 * PI * 2.0 * (time - 2.0);
            (DQuat::from_rotation_y(0.5 * phase.sin()), DVec3::new(0.05 * phase.sin(), 0.0, 0.0))
        } else {
            (DQuat::IDENTITY, DVec3::ZERO)
        };
        for ((_, rod), anchor) in strands.iter_mut().zip(&anchors) {
            rod.clamp_edge(0, turn * anchor[0] + shift, turn * anchor[1] + shift, turn * DVec3::Y)?;
            rod.step(&params, None, &mut workspace)?;
        }
        if step % 15 == 0 {
            let tips: Vec<String> = strands
                .iter()
                .map(|(_, rod)| {
                    let tip = rod.positions()[rod.node_count() - 1];
                    format!("({:+.3}, {:+.3}, {:+.3})", tip.x, tip.y, tip.z)
                })
                .collect();
            let head = if shaking { "shaking" } else { "still" };
            println!("{time:4.2} s {head:<8} {:>28} {:>28} {:>28}", tips[0], tips[1], tips[2]);
        }
    }
    for (name, rod) in &strands {
        println!(
            "{name}: largest strain {:.1e}, elastic energy {:.3e} J",
            rod.max_strain().1,
            rod.elastic_energy().total()
        );
    }
    Ok(())
}
