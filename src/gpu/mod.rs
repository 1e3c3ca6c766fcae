//! The strand step on the GPU: the same discrete elastic rods as [`crate::rod`], stepped in a WGSL compute
//! shader (`step.wgsl`) in single precision, one workgroup per strand (`gpu` feature). In an app,
//! [`HairGpuPlugin`](crate::render::HairGpuPlugin) runs it on Bevy's device; [`GpuStrandSolver`] runs it on
//! any wgpu device, with the pipelines of [`GpuStepPipelines`] built once per device.
//!
//! **What it steps.** Stretching, bending and twisting with rest curvature and rest twist (curls and the
//! gravity preload carry over from the CPU's rods), BDF2 (backward Euler on the first step), the root edge
//! clamped to its head (or nothing held: a free strand, [`GpuStrandInput::rod`]), gravity, air drag relative to the air's velocity, internal damping,
//! inextensibility, contact with the head's colliders of every shape with Coulomb friction (spheres,
//! capsules, ellipsoids at their closest point, planes, boxes sharp or rounded, and meshes through their
//! baked distance fields, uploaded once and sampled trilinearly), the style hold (springs towards each strand's groomed places carried with its head,
//! [`GpuStrandInput::groomed`], as [`crate::rod::Anchor`] on the CPU), and hair–hair interaction through
//! a grid per head ([`GpuStrandSolver::set_volume`]: the velocity smoothing and volume pressure of
//! [`crate::volume`], splatted, computed and given back in six passes before the step, in `grid.wgsl`).
//!
//! **How a strand is laid out on the GPU.** Lane `i` of the strand's workgroup owns edge `i` and the node
//! at its end (lane 0 the root node too; a free strand's first node has the lane after the last edge's,
//! so a free strand takes one node fewer, [`max_free_gpu_nodes`]), their state in its registers: strands of up to 32 edges (a
//! game's guides) are stepped by workgroups of 32 lanes, one warp, longer ones (up to 64 edges,
//! [`MAX_GPU_NODES`] nodes) by workgroups of 64, and where the device has the workgroup memory (desktop
//! GPUs do) strands of up to 128 edges ([`MAX_WIDE_GPU_NODES`]) by workgroups of 128 ([`gpu_max_nodes`]);
//! the pipelines are built from one shader (its `LANES` constant) and dispatched in one pass. The banded
//! Newton system (half-bandwidth 10, up to 259 unknowns at 64 lanes, 515 at 128) lives in workgroup
//! memory (8 kB at 32 lanes, 15.5 kB at 64, of the 16 kB WebGPU guarantees; 30.7 kB at 128): each lane
//! assembles its vertex's bending and twisting (three passes, so that vertices sharing unknowns never add
//! at once) and its node's inertia, drag, stretching, hold and contact rows;
//! the `L D Lᵀ` factorisation goes column by column, the 55 entries of each column's trailing update made by
//! as many lanes, and the substitutions (chains of dependent steps) are one lane's. The projection's
//! tridiagonal system (one equation per edge) is solved by parallel cyclic reduction in five rounds for 32
//! edges. Buffers are row planes of node-contiguous strands, so a workgroup's lanes read neighbouring
//! memory and no strand is padded to the longest.
//!
//! **Single precision, and what differs from the CPU.** WebGPU has no `f64`. Three choices keep the step
//! honest in `f32`:
//! - *Inextensibility by projection, not by a stiff spring in the solve.* Hair's stretching stiffness
//!   `EA/l` is ~10⁷ times a node's inertia `m/h²` at 60 Hz; in a solve with it, `f32` rounding (10⁻⁷
//!   relative) of the stiff terms would swamp the soft modes that make the motion. The GPU's solve keeps
//!   an edge's first-order change of length only [`STRETCH_RATIO`] (10³) times stiffer than its nodes'
//!   inertia (condition ~10³, so `f32` solves it to ~10⁻⁴) and has no stretching force; the lengths are
//!   then projected exactly onto the rest lengths (Goldenthal et al. 2007), as the CPU projects onto its
//!   linearised lengths.
//! - *Positions relative to the head*, so that `f32` resolves tenths of a micrometre wherever the head is.
//! - *A fixed number of Newton iterations* ([`GPU_NEWTON_ITERATIONS`]) for every strand, where the CPU
//!   stops each strand when it converges.
//! - *Exits that single precision can reach.* The projection stops once every edge's strain is within what `f32`
//!   resolves where the edge lies (four times the rounding of its length from positions relative to the
//!   head: 1e-6 to 3e-5), or when an iteration no longer lowers an error that close to it; contact rounds
//!   stop when no node moved by more than its position's rounding. A dispatch runs until its slowest
//!   strand is done, so an exit below what `f32` can reach cost every strand beside it.
//! - *Contact*: springs inside the solve, as on the CPU, then a push-out after it (friction on the slip,
//!   edges dipping in between their nodes pushed out at their deepest point, lengths again), where the CPU
//!   re-solves friction inside Newton and iterates until the set of touching nodes holds. With two Newton
//!   iterations and no re-solve, three things keep resting hair at rest: an edge's push moves each node
//!   along the collider's normal at itself (not along the push, which would slide a contact's end nodes a
//!   little every step); a node an edge's push left above the surface keeps its spring that far out in the
//!   next step (it would fall a step's worth and be pushed out again); and contact is inelastic (a pushed
//!   node keeps no speed away from the surface beyond the surface's own). Where hair rests, it rests within
//!   a millimetre or a few of the CPU's (`tests/gpu/colliders.rs`).
//!
//! **Work counters.** The shader counts each strand's Newton iterations, projection iterations and
//! sweeps, contact rounds and factorisation retries ([`GpuStrandWork`], [`GpuStrandSolver::read_work`]),
//! so the work a step does is a number the tests bound on any adapter, a software one included.
//!
//! **Faults** are found on the GPU: a strand with a non-finite value, an edge strained past
//! [`crate::rod::StepParams::strain_bound`] (plus the strain `f32` can resolve,
//! [`SINGLE_PRECISION_STRAIN`]) or a system that does not factorise is put back in the pose it was uploaded
//! in, on its root, at rest, and its [`GpuStrandStatus`] says why (the reason of the last failure is kept
//! until the next, for read-backs every few steps). Contact that cannot be met with the lengths kept (a
//! strand deep inside a collider that holds its root) is given up for the step rather than failing it;
//! a collider holding a root inside it leaves the strand within twice the root's depth free of it, as on
//! the CPU.

mod gather;
mod grid;
mod pipelines;
mod step;

pub use gather::{GATHER_SHADER, GpuGatherTarget};
pub use grid::{GPU_GRID_POINTS, GRID_SHADER, GpuGridFields, GpuGridPoint, GpuVolume};
pub use pipelines::{bind_whole_buffers, compute_layout, compute_pipeline, pipeline_of_module};
pub(crate) use step::root_held;
pub use step::{
    GPU_CONTACT_ROUNDS, GPU_FOLD_GAP, GPU_NEWTON_ITERATIONS, GpuFault, GpuHairCadence, GpuHeadStep, GpuReadBack,
    GpuStepError, GpuStepPipelines, GpuStepTimings, GpuStrandInput, GpuStrandSolver, GpuStrandStates, GpuStrandStatus,
    GpuStrandUpload, GpuStrandWork, MAX_GPU_NODES, MAX_GPU_SPAN, MAX_WIDE_GPU_NODES, SINGLE_PRECISION_STRAIN,
    STEP_SHADER, STRETCH_RATIO, gpu_max_nodes, gpu_step_support, headless_device, max_free_gpu_nodes,
};
