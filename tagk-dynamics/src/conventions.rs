//! [vehicle-file]: crate::conventions::vehicle_file
//! [column-mapping]: crate::conventions::column_mapping
//! [model-file]: https://docs.rs/tagk-diagnose/latest/tagk_diagnose/model_file/format/index.html
#![doc = include_str!("../docs/CONVENTIONS.md")]

/// The vehicle file: `docs/VEHICLE.md`.
pub mod vehicle_file {
    #![doc = include_str!("../docs/VEHICLE.md")]
}

/// The column mapping: `docs/COLUMN_MAPPING.md`.
pub mod column_mapping {
    #![doc = include_str!("../docs/COLUMN_MAPPING.md")]
}
