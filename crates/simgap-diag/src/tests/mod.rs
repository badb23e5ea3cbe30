//! Tests of the stages' internals (the public API is tested from `tests/`).

mod alternatives;
mod backlash;
mod common;
mod delay_line;
mod encoder_offset;
mod friction_filter;
mod gram_cache;
mod intervals;
mod kstep_groups;
mod link_side;
mod lowpass;
mod not_tried;
mod payload;
mod physical;
mod pitfalls;
mod rebuild;
mod residual_floor;
mod servo;
mod shooting;
mod spring;
