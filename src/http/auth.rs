//! Bearer-token authentication and the tenant of a request.
//!
//! The token file (`--auth-tokens FILE`) holds one `token tenant` pair per
//! line; `#` starts a comment line and blank lines are skipped. A token is at
//! least [`MIN_TOKEN_LEN`] visible ASCII characters, a tenant name 1–64 of
//! `A-Z a-z 0-9 . _ -`; a tenant may have several tokens (rotation), a token
//! belongs to one tenant. Tokens are kept only as SHA-256 digests: a
//! presented token is hashed and its digest compared with every stored one
//! by a constant-time comparison, so neither the table in memory nor the
//! response time gives a token away.
//!
//! With tokens configured, every route except `/healthz` (and `/metrics`
//! unless `--metrics-auth`, and the browser pages' static shell, which holds
//! no data) needs `Authorization: Bearer TOKEN`; a missing
//! token answers 401 `unauthorized` with `WWW-Authenticate: Bearer
//! realm="meshatlas"`, a wrong one adds `error="invalid_token"` (RFC 6750).
//! The middleware ([`authenticate`]) puts the caller's [`Tenant`] into the
//! request extensions, and handlers read it as a [`Scope`].
//!
//! SIGHUP reloads the file ([`reload_on_sighup`]); a file that does not
//! parse keeps the tokens in force and logs why.

use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock};

use axum::extract::{FromRequestParts, Request, State};
use axum::http::request::Parts;
use axum::http::{HeaderMap, HeaderValue, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};

use super::AppState;
use super::error::ApiError;
use crate::failure::FailureKind;

/// Shortest accepted token, in characters.
pub const MIN_TOKEN_LEN: usize = 16;
/// Longest accepted token, in characters.
pub const MAX_TOKEN_LEN: usize = 1024;
/// Longest accepted tenant name, in characters.
pub const MAX_TENANT_LEN: usize = 64;
/// The `realm` of the Bearer challenge.
pub const REALM: &str = "meshatlas";

/// Why a token file was refused. Messages name the line, never a token.
#[derive(Debug, thiserror::Error)]
pub enum TokenFileError {
    /// The file cannot be read.
    #[error("cannot read the token file {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// A line is not a valid `token tenant` pair.
    #[error("token file {path} line {line}: {what}")]
    Line {
        /// The file.
        path: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        what: String,
    },
    /// Only comments and blank lines.
    #[error("token file {path}: no token (every line is blank or a comment)")]
    Empty {
        /// The file.
        path: String,
    },
}

/// The tenant an authenticated request acts for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Tenant(pub Arc<str>);

/// One token of the table, by digest.
struct Entry {
    digest: [u8; 32],
    tenant: Arc<str>,
}

/// Tokens (as SHA-256 digests) and their tenants.
pub struct TokenTable {
    entries: Vec<Entry>,
}

/// SHA-256 of a token.
fn digest(token: &str) -> [u8; 32] {
    Sha256::digest(token.as_bytes()).into()
}

/// Equality of two digests in time independent of where they differ.
fn digests_equal(a: &[u8; 32], b: &[u8; 32]) -> bool {
    let diff = a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y));
    std::hint::black_box(diff) == 0
}

/// True for a valid tenant name.
fn valid_tenant(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_TENANT_LEN
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'))
}

impl TokenTable {
    /// Parses the text of a token file; `path` only names it in errors.
    ///
    /// # Errors
    /// [`TokenFileError::Line`] for a malformed line, a short or long token,
    /// a bad tenant name or a token given twice; [`TokenFileError::Empty`]
    /// when there is no token.
    pub fn parse(text: &str, path: &str) -> Result<Self, TokenFileError> {
        let mut entries: Vec<(usize, Entry)> = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = i + 1;
            let bad = |what: String| TokenFileError::Line { path: path.to_string(), line, what };
            let trimmed = raw.trim();
            if trimmed.is_empty() || trimmed.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = trimmed.split_ascii_whitespace().collect();
            let [token, tenant] = fields[..] else {
                return Err(bad(format!("expected `token tenant`, found {} field(s)", fields.len())));
            };
            let n = token.chars().count();
            if n < MIN_TOKEN_LEN {
                return Err(bad(format!("the token has {n} characters; at least {MIN_TOKEN_LEN} are required")));
            }
            if n > MAX_TOKEN_LEN || !token.bytes().all(|b| b.is_ascii_graphic()) {
                return Err(bad(format!("a token is at most {MAX_TOKEN_LEN} visible ASCII characters")));
            }
            if !valid_tenant(tenant) {
                return Err(bad(format!("a tenant name is 1–{MAX_TENANT_LEN} of A-Z a-z 0-9 . _ -")));
            }
            let d = digest(token);
            if let Some((first, _)) = entries.iter().find(|(_, e)| e.digest == d) {
                return Err(bad(format!("the token of line {first} is given again")));
            }
            entries.push((line, Entry { digest: d, tenant: Arc::from(tenant) }));
        }
        if entries.is_empty() {
            return Err(TokenFileError::Empty { path: path.to_string() });
        }
        Ok(Self { entries: entries.into_iter().map(|(_, e)| e).collect() })
    }

    /// Reads and parses the token file at `path`.
    ///
    /// # Errors
    /// [`TokenFileError`] as for [`TokenTable::parse`], or when unreadable.
    pub fn load(path: &Path) -> Result<Self, TokenFileError> {
        let shown = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|source| TokenFileError::Read { path: shown.clone(), source })?;
        Self::parse(&text, &shown)
    }

    /// Number of tokens.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when there is no token (never for a parsed table).
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The tenant of `token`, comparing its digest with every entry (no
    /// early exit, constant-time comparison).
    pub fn tenant_of(&self, token: &str) -> Option<Tenant> {
        let d = digest(token);
        let mut found = None;
        for e in &self.entries {
            if digests_equal(&e.digest, &d) {
                found = Some(e.tenant.clone());
            }
        }
        found.map(Tenant)
    }
}

/// Authentication settings in force: the token file and its current table.
pub struct Auth {
    path: PathBuf,
    table: RwLock<Arc<TokenTable>>,
    /// `/metrics` also needs a token.
    pub metrics_auth: bool,
}

impl Auth {
    /// Loads the token file at `path`.
    ///
    /// # Errors
    /// [`TokenFileError`] when the file is unreadable or invalid.
    pub fn load(path: &Path, metrics_auth: bool) -> Result<Self, TokenFileError> {
        let table = TokenTable::load(path)?;
        Ok(Self { path: path.to_path_buf(), table: RwLock::new(Arc::new(table)), metrics_auth })
    }

    /// Re-reads the token file; on error the tokens in force stay. Returns
    /// the number of tokens now in force.
    ///
    /// # Errors
    /// [`TokenFileError`] when the file is unreadable or invalid.
    pub fn reload(&self) -> Result<usize, TokenFileError> {
        let table = TokenTable::load(&self.path)?;
        let n = table.len();
        *self.table.write().unwrap_or_else(|p| p.into_inner()) = Arc::new(table);
        Ok(n)
    }

    /// The tenant of `token` under the table in force.
    pub fn tenant_of(&self, token: &str) -> Option<Tenant> {
        let table = self.table.read().unwrap_or_else(|p| p.into_inner()).clone();
        table.tenant_of(token)
    }

    /// True when `req` needs a token: everything but `/healthz`, the browser
    /// pages' static shell and assets ([`super::page::is_public`]), and
    /// `/metrics` only with `--metrics-auth`.
    fn needs_token(&self, req: &Request) -> bool {
        let path = req.uri().path();
        if super::page::is_public(req.method(), path, req.headers()) {
            return false;
        }
        match path {
            "/healthz" => false,
            "/metrics" => self.metrics_auth,
            _ => true,
        }
    }
}

/// Reloads `auth` from its file on every SIGHUP (Unix), logging the outcome.
///
/// # Errors
/// The OS error when the signal handler cannot be installed.
pub fn reload_on_sighup(auth: Arc<Auth>) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        let mut hup = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::hangup())?;
        tokio::spawn(async move {
            while hup.recv().await.is_some() {
                let a = auth.clone();
                match tokio::task::spawn_blocking(move || a.reload()).await {
                    Ok(Ok(n)) => tracing::info!(tokens = n, "token file reloaded"),
                    Ok(Err(e)) => {
                        tracing::error!(error = %e, "token file not reloaded; the previous tokens stay in force")
                    }
                    Err(e) => tracing::error!(error = %e, "token file reload failed"),
                }
            }
        });
    }
    #[cfg(not(unix))]
    let _ = auth;
    Ok(())
}

/// What the `Authorization` header presents.
enum Presented<'a> {
    /// No header, or another scheme than Bearer.
    Nothing,
    /// A Bearer token (possibly empty).
    Bearer(&'a str),
}

/// The Bearer token of the request, if any (scheme case-insensitive).
fn presented(headers: &HeaderMap) -> Presented<'_> {
    let Some(value) = headers.get(header::AUTHORIZATION) else { return Presented::Nothing };
    let Ok(text) = value.to_str() else { return Presented::Bearer("") };
    match text.trim().split_once(' ') {
        Some((scheme, token)) if scheme.eq_ignore_ascii_case("bearer") => Presented::Bearer(token.trim()),
        None if text.trim().eq_ignore_ascii_case("bearer") => Presented::Bearer(""),
        _ => Presented::Nothing,
    }
}

/// The 401 answer with its Bearer challenge (`invalid_token` when a token
/// was given but is not valid).
fn challenge(invalid_token: bool) -> Response {
    let (detail, value) = if invalid_token {
        ("the bearer token is not valid", format!("Bearer realm=\"{REALM}\", error=\"invalid_token\""))
    } else {
        ("this route needs an `Authorization: Bearer TOKEN` header", format!("Bearer realm=\"{REALM}\""))
    };
    let mut resp = ApiError::new(FailureKind::Unauthorized, detail).into_response();
    if let Ok(v) = HeaderValue::from_str(&value) {
        resp.headers_mut().insert(header::WWW_AUTHENTICATE, v);
    }
    resp
}

/// Middleware: with tokens configured, lets a request through only with a
/// valid Bearer token and records its [`Tenant`] in the extensions. A
/// refused request's body is drained (bounded), so the client reads the 401.
pub async fn authenticate(State(st): State<AppState>, mut req: Request, next: Next) -> Response {
    let Some(auth) = st.auth.as_deref() else { return next.run(req).await };
    if !auth.needs_token(&req) {
        return next.run(req).await;
    }
    let verdict = match presented(req.headers()) {
        Presented::Nothing => Err(false),
        Presented::Bearer(token) => auth.tenant_of(token).ok_or(true),
    };
    match verdict {
        Ok(tenant) => {
            req.extensions_mut().insert(tenant);
            next.run(req).await
        }
        Err(invalid_token) => {
            super::upload::drain(req.into_body().into_data_stream()).await;
            challenge(invalid_token)
        }
    }
}

/// Whose jobs a request may see: the caller's tenant, or `None` (every
/// job) when authentication is off. Refuses (500) a request that reached a
/// handler without a tenant while authentication is on, so a routing
/// mistake cannot open every job.
#[derive(Debug, Clone)]
pub struct Scope(pub Option<Tenant>);

impl Scope {
    /// The tenant name for the job service (`None`: unscoped).
    pub fn tenant(&self) -> Option<String> {
        self.0.as_ref().map(|t| t.0.to_string())
    }
}

impl FromRequestParts<AppState> for Scope {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Self, Self::Rejection> {
        match (parts.extensions.get::<Tenant>(), &state.auth) {
            (Some(t), _) => Ok(Self(Some(t.clone()))),
            (None, None) => Ok(Self(None)),
            (None, Some(_)) => {
                Err(ApiError::internal("a request reached a handler without a tenant while authentication is on"))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: &str = "0123456789abcdef-a";
    const B: &str = "0123456789abcdef-b";

    fn line_of(e: TokenFileError) -> usize {
        match e {
            TokenFileError::Line { line, .. } => line,
            other => panic!("not a line error: {other}"),
        }
    }

    #[test]
    fn parses_comments_blanks_and_several_tokens_per_tenant() {
        let t = TokenTable::parse(&format!("# tenants\n\n  {A}  alpha  \n{B}\talpha\n"), "f").unwrap();
        assert_eq!(t.len(), 2);
        assert_eq!(t.tenant_of(A), Some(Tenant(Arc::from("alpha"))));
        assert_eq!(t.tenant_of(B), Some(Tenant(Arc::from("alpha"))));
        assert_eq!(t.tenant_of("0123456789abcdef-c"), None);
        assert_eq!(t.tenant_of(""), None);
    }

    #[test]
    fn rejects_bad_lines_with_their_number_and_without_the_token() {
        let cases = [
            (format!("{A} a\nshort b\n"), 2),
            (format!("{A} a\n# x\n{A} b\n"), 3),
            (format!("{A} a b\n"), 1),
            (format!("\n\n{A}\n"), 3),
            (format!("{A} a/b\n"), 1),
            (format!("{A}\u{7f} a\n"), 1),
        ];
        for (text, line) in cases {
            let e = TokenTable::parse(&text, "f").err().unwrap_or_else(|| panic!("accepted {text:?}"));
            assert!(!e.to_string().contains(A), "{e}");
            assert_eq!(line_of(e), line, "{text:?}");
        }
        assert!(matches!(TokenTable::parse("# only\n\n", "f"), Err(TokenFileError::Empty { .. })));
    }

    #[test]
    fn digests_compare_equal_only_when_equal() {
        let a = digest(A);
        let mut b = a;
        assert!(digests_equal(&a, &b));
        b[31] ^= 1;
        assert!(!digests_equal(&a, &b));
        // Known SHA-256 answer ("abc", FIPS 180-2).
        let abc = digest("abc");
        assert_eq!(abc[..4], [0xba, 0x78, 0x16, 0xbf]);
    }

    #[test]
    fn bearer_header_parsing() {
        let h = |v: &str| {
            let mut m = HeaderMap::new();
            m.insert(header::AUTHORIZATION, HeaderValue::from_str(v).unwrap());
            m
        };
        assert!(matches!(presented(&HeaderMap::new()), Presented::Nothing));
        assert!(matches!(presented(&h("Basic YTpi")), Presented::Nothing));
        assert!(matches!(presented(&h("Bearer abc")), Presented::Bearer("abc")));
        assert!(matches!(presented(&h("bearer   abc ")), Presented::Bearer("abc")));
        assert!(matches!(presented(&h("Bearer")), Presented::Bearer("")));
    }
}
