//! Tests of the stages' internals (the public API is tested from `tests/`).

pub(crate) mod common;
mod delay_line;
mod friction_filter;
mod gram_cache;
mod intervals;
mod link_side;
mod physical;
mod pitfalls;
mod rebuild;
mod servo;
mod shooting;
mod spring;
