//! The mechanics core (`bevy_hair_sim::rod`, `groom`) against numbers, with no app: analytic solutions,
//! conservation, convergence orders, and bad input refused. `cargo test --test mechanics`.

mod boundary_conditions;
mod cantilever;
mod contact;
mod faults;
mod groom;
mod integrator;
mod preload;
mod real_hair;
mod rest_shape;
mod twist;
