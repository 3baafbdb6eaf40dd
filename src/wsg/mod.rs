//! The `wsg` protocol (under construction).
