//! gripsim: a simulator and visual logging/replay tool for soft grippers grasping fruit.
//!
//! Each prong is a planar discrete elastic rod (stretching and bending springs between
//! nodes), integrated with implicit Euler and Newton. Contact with rigid obstacles (the
//! fruit) uses the modified mass method. The physics core ([`energy`], [`obstacle`],
//! [`model`], [`solver`]) does no I/O; it reports what happens through
//! [`events::Observer`], and every sink in [`record`] is one observer.

// Numerical kernels index several arrays with one loop variable (node i of q, u, the
// residual, the band); the iterator form clippy suggests would zip four or five slices and
// hide the node index the formulas are written in.
#![allow(clippy::needless_range_loop)]
// `!(x > 0.0)` is deliberate wherever it appears: it is also true for NaN, which the input
// checks and guards must refuse.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod actuation;
pub mod bench;
pub mod contact;
pub mod energy;
pub mod events;
pub mod model;
pub mod obstacle;
pub mod obstacle3;
pub mod record;
pub mod replay;
pub mod rod3d;
pub mod run;
pub mod scenario;
pub mod solver;
pub mod study;
pub mod world;

pub use scenario::Scenario;
pub use solver::Simulation;
