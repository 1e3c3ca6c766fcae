//! Prints how fast the hair simulation runs: `cargo run --release --example benchmark`.
//!
//! The real plugin in a headless app (see `benches/support/scene.rs`): 25 cm human hairs on a swaying,
//! turning head, gravity on, dt = 1/60 s. A row's time is the median wall time of the measured steps
//! (the whole fixed step: pinning roots, stepping strands, writing poses), after the hair has fallen and
//! started to swing.
//!
//! Arguments: the tables to print (`scaling`, `collisions`, `parallel`, `memory`; all by default), `--quick` to measure
//! fewer steps, `--threads N` for the compute threads (one per core by default). Bevy's task pools are
//! set once per process, so the parallel table runs this program again with `--threads`.

#[path = "../benches/support/counting_allocator.rs"]
mod counting_allocator;
#[path = "../benches/support/scene.rs"]
mod scene;

use std::process::Command;
use std::sync::atomic::Ordering;
use std::time::Instant;

use bevy::tasks::available_parallelism;
use counting_allocator::BYTES_IN_USE;
use scene::Scene;

/// Median wall time of `steps` steps, s, after the warm-up, with `colliders` colliders.
fn median_step_seconds(strands: usize, edges: usize, colliders: usize, threads: usize, steps: usize) -> f64 {
    let mut scene = Scene::new(strands, edges, Some(threads)).with_colliders(colliders);
    scene.warm_up();
    let mut times: Vec<f64> = (0..steps)
        .map(|_| {
            let started = Instant::now();
            scene.step();
            started.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

/// Median wall time per step of each scene, s, after the warm-up, stepping them in turn so that the
/// machine's slow drifts fall on all alike.
fn interleaved_median_step_seconds(scenes: &mut [Scene], steps: usize) -> Vec<f64> {
    scenes.iter_mut().for_each(Scene::warm_up);
    let mut times = vec![Vec::with_capacity(steps); scenes.len()];
    for _ in 0..steps {
        for (scene, times) in scenes.iter_mut().zip(&mut times) {
            let started = Instant::now();
            scene.step();
            times.push(started.elapsed().as_secs_f64());
        }
    }
    times
        .into_iter()
        .map(|mut times| {
            times.sort_by(f64::total_cmp);
            times[times.len() / 2]
        })
        .collect()
}

/// The value following `flag` in `args`, parsed.
fn flag_value(args: &[String], flag: &str) -> Option<usize> {
    let position = args.iter().position(|arg| arg == flag)?;
    let value = args.get(position + 1)?;
    Some(value.parse().unwrap_or_else(|_| panic!("{flag} needs a number, got {value:?}")))
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|arg| arg == "--quick");
    let steps = if quick { 15 } else { 60 };
    let cores = available_parallelism();
    let threads = flag_value(&args, "--threads").unwrap_or(cores);
    if args.first().is_some_and(|arg| arg == "measure") {
        let number = |index: usize| args.get(index).and_then(|arg| arg.parse().ok());
        let (strands, edges) = number(1).zip(number(2)).expect("measure STRANDS EDGES [COLLIDERS]");
        let colliders = number(3).unwrap_or(0);
        println!("{}", median_step_seconds(strands, edges, colliders, threads, steps));
        return;
    }
    let tables: Vec<&str> = args
        .iter()
        .enumerate()
        .filter(|&(index, arg)| !arg.starts_with("--") && (index == 0 || args[index - 1] != "--threads"))
        .map(|(_, arg)| arg.as_str())
        .collect();
    let wanted = |table: &str| tables.is_empty() || tables.contains(&table);
    println!("bevy_hair_sim benchmark: {cores} cores, {threads} compute threads, {steps} measured steps per row");
    if wanted("scaling") {
        scaling(threads, steps);
    }
    if wanted("collisions") {
        collisions(threads, steps);
    }
    if wanted("parallel") {
        parallel_efficiency(cores, quick);
    }
    if wanted("memory") {
        memory_per_node(threads);
    }
}

/// Cost against strands and edges, with the ratio to the row with half as many.
fn scaling(threads: usize, steps: usize) {
    println!();
    println!("| strands | edges | ms / step | M node-steps / s | × previous strands | × previous edges |");
    println!("|---:|---:|---:|---:|---:|---:|");
    let strand_counts = [1, 100, 1000, 2000, 4000];
    let mut previous_edges = [None; 5];
    for edges in [16, 32, 64] {
        let mut previous_strands: Option<f64> = None;
        for (row, strands) in strand_counts.into_iter().enumerate() {
            let seconds = median_step_seconds(strands, edges, 0, threads, steps);
            let node_steps = (strands * (edges + 1)) as f64 / seconds;
            let ratio = |previous: Option<f64>| previous.map_or(String::new(), |p| format!("{:.2}", seconds / p));
            println!(
                "| {strands} | {edges} | {:.3} | {:.2} | {} | {} |",
                1e3 * seconds,
                1e-6 * node_steps,
                ratio(previous_strands),
                ratio(previous_edges[row])
            );
            previous_strands = Some(seconds);
            previous_edges[row] = Some(seconds);
        }
    }
}

/// Cost against strands and colliders (skull, face, neck, shoulders, torso), 32 edges: the collision
/// share is the extra time over the same scene with no colliders, stepped in turn with it.
fn collisions(threads: usize, steps: usize) {
    const COLLIDER_COUNTS: [usize; 3] = [0, 1, 5];
    println!();
    println!("Collisions, 32 edges, colliders: skull, face, neck, shoulders, torso in that order:");
    println!("| strands | colliders | ms / step | collision share of the step | µs per strand |");
    println!("|---:|---:|---:|---:|---:|");
    for strands in [500, 1000, 2000] {
        let mut scenes =
            COLLIDER_COUNTS.map(|colliders| Scene::new(strands, 32, Some(threads)).with_colliders(colliders));
        let seconds = interleaved_median_step_seconds(&mut scenes, steps);
        let without = seconds[0];
        for (colliders, seconds) in COLLIDER_COUNTS.into_iter().zip(seconds) {
            let extra = seconds - without;
            println!(
                "| {strands} | {colliders} | {:.3} | {:.0} % | {:.2} |",
                1e3 * seconds,
                100.0 * extra / seconds,
                1e6 * extra / strands as f64
            );
        }
    }
}

/// One compute thread against one per core, each in a process of its own.
fn parallel_efficiency(cores: usize, quick: bool) {
    let run = |threads: usize| -> f64 {
        let mut command = Command::new(std::env::current_exe().expect("the benchmark's own path"));
        command.args(["measure", "2000", "32", "--threads", &threads.to_string()]);
        if quick {
            command.arg("--quick");
        }
        let output = command.output().expect("the benchmark runs itself");
        String::from_utf8_lossy(&output.stdout).trim().parse().expect("a time in seconds")
    };
    let one = run(1);
    let all = run(cores);
    println!();
    println!("Parallel efficiency, 2 000 strands × 32 edges:");
    println!("| compute threads | ms / step | speed-up |");
    println!("|---:|---:|---:|");
    println!("| 1 | {:.2} | 1.00 |", 1e3 * one);
    println!("| {cores} | {:.2} | {:.2} |", 1e3 * all, one / all);
}

/// Heap bytes per simulated node: everything the plugin keeps for 2 000 strands × 32 edges (rods,
/// solver workspaces, drawn poses, forces, entities), over their node count.
fn memory_per_node(threads: usize) {
    let (strands, edges) = (2000, 32);
    let before = BYTES_IN_USE.load(Ordering::Relaxed);
    let mut empty = Scene::new(0, edges, Some(threads));
    empty.step();
    empty.step();
    let without_hair = BYTES_IN_USE.load(Ordering::Relaxed) - before;
    drop(empty);
    let before = BYTES_IN_USE.load(Ordering::Relaxed);
    let mut scene = Scene::new(strands, edges, Some(threads));
    scene.step();
    scene.step();
    let with_hair = BYTES_IN_USE.load(Ordering::Relaxed) - before;
    let nodes = strands * (edges + 1);
    println!();
    println!("Memory, {strands} strands × {edges} edges ({nodes} nodes):");
    println!("| heap in use | bytes per node |");
    println!("|---:|---:|");
    println!(
        "| {:.1} MB | {:.0} |",
        1e-6 * (with_hair - without_hair) as f64,
        (with_hair - without_hair) as f64 / nodes as f64
    );
}
