//! Any bytes given to the MCAP reader give a run or a clean error: never a panic, an abort or a
//! hang. libFuzzer's panic hook reports a panic inside the reader even though `read_mcap_bytes`
//! would return it as an error.
#![no_main]

use libfuzzer_sys::fuzz_target;
use simgap_log::{read_mcap_bytes, LogOptions};

fuzz_target!(|data: &[u8]| {
    match read_mcap_bytes("fuzz.mcap", data, &LogOptions::default()) {
        Ok(read) => assert!(read.run.len() <= data.len(), "more samples than bytes"),
        Err(e) => assert!(!e.to_string().contains("internal error"), "the reader panicked: {e}"),
    }
});
