//! Element matrices of plane linear elasticity.
