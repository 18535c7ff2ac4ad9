//! Built-in synthetic scenes (being written in a parallel branch).
