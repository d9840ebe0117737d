//! One module per integrator, plus the registry.
