//! The `griplink` protocol (under construction).
