//! Rigid obstacles and the contact operator: B and g0 from boundary normals.
