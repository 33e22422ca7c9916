//! Stage 3: 3D discrete elastic rods (Bergou et al. 2008/2010, the method of DisMech):
//! centreline nodes in R³ plus one material angle per edge, reference frames carried by
//! time-parallel transport, material frames, stretching, bending with two stiffnesses
//! (EI₁, EI₂ of the section) and twisting (GJ), natural curvature and twist from the rest
//! shape; implicit Euler + Newton with a banded solve, static equilibria by load ramp.
//! Like the planar core it does no I/O.

pub mod dual;
pub mod energy;
pub mod events;
pub mod kernel;
pub mod rod;
pub mod section;
pub mod solver;
pub mod symband;

pub use rod::{Rod3, Rod3Spec};
pub use section::Section3;
pub use solver::{Sim3, Solve3Error};
pub use world::{ContactSide3, StepReport3, World3};
pub mod body3;
pub mod contact3;
pub mod edge3;
pub mod gripper;
pub mod limits;
pub mod run3;
pub mod spatial;
pub mod system;
pub mod world;
