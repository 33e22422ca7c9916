//! gripsim: a simulator and visual logging/replay tool for soft grippers grasping fruit.
//!
//! Each prong is a planar discrete elastic rod (stretching and bending springs between
//! nodes), integrated with implicit Euler and Newton. Contact with rigid obstacles (the
//! fruit) uses the modified mass method. The physics core ([`energy`], [`obstacle`],
//! [`model`], [`solver`]) does no I/O; it reports what happens through
//! [`events::Observer`], and every sink in [`record`] is one observer.

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
pub mod scenario;
pub mod solver;
pub mod study;
pub mod world;

pub use scenario::Scenario;
pub use solver::Simulation;
