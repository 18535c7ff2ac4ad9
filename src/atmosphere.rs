//! atmosphere (in progress)
