//! Geometry helpers: convex polyhedra, mass properties and shape statistics of stones.
