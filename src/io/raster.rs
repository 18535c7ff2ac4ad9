//! Single-plane product writers (being written in a parallel branch).
