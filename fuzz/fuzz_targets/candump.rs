//! Fuzz the candump `-L` log reader (jointlab-can's `candump`): any bytes, read line by line as
//! `hil-host replay` reads a file, must give records or a line-numbered error, never a panic;
//! every record written back as a log line must parse to the same record.
#![no_main]

use jointlab_can::candump::{parse_line, CandumpReader};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|input: &[u8]| {
    for (k, rec) in CandumpReader::new(input).enumerate() {
        let Ok(rec) = rec else {
            // The first bad line ends a read (`read_log` stops there too).
            break;
        };
        let line = rec.to_string();
        let again = parse_line(&line, k + 1)
            .unwrap_or_else(|e| panic!("record {rec:?} wrote `{line}`, which fails: {e}"))
            .unwrap_or_else(|| panic!("record {rec:?} wrote a blank line"));
        assert_eq!(again, rec, "`{line}` parses to another record");
    }
});
