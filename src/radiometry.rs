//! radiometry (in progress)
