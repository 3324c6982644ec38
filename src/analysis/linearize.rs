//! Linearisation (in progress).
