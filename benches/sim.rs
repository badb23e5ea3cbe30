//! Closed-loop simulation benchmarks (placeholder replaced below).
fn main() {}
