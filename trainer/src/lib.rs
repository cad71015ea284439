//! placeholder
pub use snerf_data as data;
