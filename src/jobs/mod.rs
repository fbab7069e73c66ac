//! Durable jobs: model, SQLite store, runner bridging tokio and the rayon pool.
