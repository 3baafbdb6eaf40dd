//! The `smartgrasp` protocol (under construction).
