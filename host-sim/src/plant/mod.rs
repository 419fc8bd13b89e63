//! The hydraulic plant of `shared/PLANT.md` (in progress).
