//! The bench robots with hidden effects ([`bench`]) and the blind self-check over random
//! scenarios drawn from them ([`selfcheck`]).

pub mod bench;
pub mod drives;
pub mod selfcheck;
