//! motion (in progress)
