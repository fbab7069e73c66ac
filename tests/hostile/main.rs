//! The service under a careless or hostile client (issue 11): every test
//! starts the real `meshatlas serve` binary on a loopback port with a fresh
//! data directory, and talks to it over HTTP (reqwest, or raw TCP where the
//! defect lives below HTTP clients' politeness).
//!
//! One module per area; each test is named for the defect it pins down and
//! failed on the code before its fix.

mod common;

mod auth;
mod downloads;
mod http_limits;
mod memory;
mod readers;
mod requests;
mod soak;
mod storage;
