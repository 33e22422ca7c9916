//! The integration tests, one binary (each module was a test binary of its own; linking 20
//! copies of the Rerun SDK cost minutes and gigabytes). alloc.rs and replay_memory.rs stay
//! separate: they install a counting global allocator.

mod auto_detail;
mod bad_input;
mod bad_recordings;
mod bad_recordings3d;
mod bench;
mod common;
mod compliant3d;
mod contact3d;
mod contact_geometry;
mod edge3d;
mod edge_friction;
mod events_dim;
mod faults;
mod fin_ray;
mod fin_ray_roller;
mod first_contact;
mod friction_bodies;
mod friction_pull;
mod frictionless_golden;
mod fruit;
mod fruit_records;
mod grasp3d;
mod hostile3d;
mod integrator;
mod joints;
mod joints_bodies;
mod no_data_loss;
mod pick_and_place;
mod planar_identity;
mod properties;
mod rec3d;
mod recordings;
mod regressions;
mod replay;
mod replay_guard;
mod rod3d;
mod rrd_view;
mod static_contact;
mod stepping;
mod summary_schema;
mod sweep;
mod verification;
mod window;
