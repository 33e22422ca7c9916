//! Contact: where the prongs and the fruit touch, the constraint a contact imposes, and the
//! decisions taken on it.
//!
//! - [`surfaces`]: every surface a node can touch — fixed obstacles, and free bodies at a pose.
//! - [`detect`]: closest surfaces and penetrations (a cheap bound first).
//! - [`constraint`]: what a contact holds (the normal only, or the whole node: stuck or in a
//!   corner), on a fixed surface or relative to a moving body.
//! - [`friction`]: Coulomb coefficients and the stick/slip decisions — friction is decided
//!   there and nowhere else.
//! - [`edge`]: a segment's interior point held on an obstacle (edge contact).
//! - [`body`]: a free body's own contacts with fixed obstacles (a fruit on a table).
//! - [`compliant`]: a fruit of elastic material: the Hertz line-contact law, solved implicitly.
//! - [`conforming`]: the same fruit pressed along the prong (edge mode): a pressure
//!   distributed over the contact arc, one contact per connected arc.

pub mod body;
pub mod compliant;
pub mod conforming;
pub mod constraint;
pub mod detect;
pub mod edge;
pub mod friction;
pub mod surfaces;

pub use constraint::{BodyLink, Constraint, Corner, Grip, LawHold};
pub use detect::*;
pub use surfaces::Surfaces;
