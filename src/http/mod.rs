//! The HTTP API (axum): routes, handlers, problem+json errors, OpenAPI.
