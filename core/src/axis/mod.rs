//! Axis control laws (in progress).
