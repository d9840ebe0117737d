//! Machinery several integrators share.

pub mod direct;
