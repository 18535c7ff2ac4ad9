//! spectrum (in progress)
