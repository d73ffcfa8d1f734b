//! Streaming, allocation-free depth metrics.
