//! Every reader, with and without a known size, on arbitrary bytes: must
//! return `Ok` with a valid mesh or an error, never panic or hang.
#![no_main]

use libfuzzer_sys::fuzz_target;
use meshatlas::io::{Format, LoadOptions, load_bytes, load_reader};

fuzz_target!(|data: &[u8]| {
    let opts = LoadOptions { max_triangles: 100_000, ..LoadOptions::default() };
    let Some((&selector, bytes)) = data.split_first() else { return };
    let format = Format::ALL[selector as usize % 4];
    for result in [load_bytes(bytes, Some(format), &opts), load_reader(bytes, format, &opts), load_bytes(bytes, None, &opts)] {
        if let Ok(l) = result {
            assert!(l.surface.validate().is_ok());
            assert!(l.volume.is_none_or(|v| v.validate().is_ok()));
        }
    }
});
