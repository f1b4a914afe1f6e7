//! The column mapping and the stream merge on arbitrary input: the bytes up to the first NUL are
//! a mapping (TOML), the rest a stream (CSV) read through it. Every outcome must be a mapping
//! error, a typed input error or a validated log: never a panic. The merge report (stream
//! rates and spans, warnings, unread columns) is rendered too. `seeds/column_mapping/new_keys`
//! holds the keys of issue #25 (eRPM with pole pairs, a numeric factor, `accel =
//! "specific-force"`, `normalize_quaternion`, `ignore`, an extra column renamed) and text in
//! unmapped columns.
#![no_main]

use std::io::Write;

use libfuzzer_sys::fuzz_target;
use tagk_dynamics::log_input::{ColumnMapping, ReadOptions, read_streams};

fuzz_target!(|data: &[u8]| {
    let split = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    let Ok(toml) = std::str::from_utf8(&data[..split]) else {
        return;
    };
    let Ok(mapping) = ColumnMapping::from_toml_str(toml) else {
        return;
    };
    let csv = data.get(split + 1..).unwrap_or_default();
    // One file per fuzzing process, in memory-backed /dev/shm when there is one.
    let dir = if std::path::Path::new("/dev/shm").is_dir() {
        std::path::PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    let path = dir.join(format!("tagk-fuzz-{}.csv", std::process::id()));
    let mut file = std::fs::File::create(&path).expect("temporary file");
    file.write_all(csv).expect("temporary file");
    drop(file);
    if let Ok((log, report)) = read_streams(&[path], &mapping, &ReadOptions::default()) {
        log.validate().expect("a merged log validates");
        let _ = report.text();
        for s in &report.streams {
            assert!(s.dropped <= log.len() + report.dropped_in_gaps + report.dropped_outside);
        }
    }
});
