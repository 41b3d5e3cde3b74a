//! Roughness.
