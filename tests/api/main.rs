//! API acceptance tests: reqwest against a real server on a loopback port.
//!
//! Most tests run the router in-process (`tokio::spawn`) with either the real
//! pipeline executor or an injected one; `restart` runs the real binary and
//! kills it with SIGKILL mid-job.

mod common;
mod errors;
mod fixtures;
mod formats;
mod jobs;
mod page;
mod restart;
#[path = "../common/mod.rs"]
mod shared;
mod spec;
mod stages;
