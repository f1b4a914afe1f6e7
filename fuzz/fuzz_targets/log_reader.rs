//! The flight-log CSV reader on arbitrary bytes: it must return a log or a typed error, never
//! panic; a log it accepts must validate and survive a write → read round trip unchanged.
#![no_main]

use libfuzzer_sys::fuzz_target;
use tagk_dynamics::log::FlightLog;

fuzz_target!(|data: &[u8]| {
    let Ok(log) = FlightLog::from_csv_reader(data) else {
        return;
    };
    let _ = log.sampling();
    if log.has_wrench() {
        log.validate().expect("a log the reader accepts validates");
    }
    let mut csv = Vec::new();
    log.write_csv(&mut csv).expect("a log the reader accepts can be written");
    let back = FlightLog::from_csv_reader(csv.as_slice()).expect("what the writer writes reads");
    assert_eq!(back, log);
});
