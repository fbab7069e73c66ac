//! The browser pages: one static HTML shell with its script and style sheet,
//! embedded in the binary.
//!
//! The shell (`page/shell.html`) carries no data: the same bytes answer `GET
//! /` and every `GET /v1/jobs/{id}` whose `Accept` prefers HTML, and its
//! script (`page/app.js`) reads the job id from the URL and builds the page
//! from the JSON API with `textContent`/`createElement` (never HTML text), so
//! no server value is ever interpreted as markup. Because the shell is the
//! same for every path, it is served without a token ([`is_public`]): it
//! cannot tell whether a job exists, let alone whose it is. The script asks
//! for a token only when the JSON API answers 401, keeps it in
//! `sessionStorage`, and then loads images and downloads through `fetch`
//! with the `Authorization` header (object URLs).
//!
//! Content negotiation ([`prefers_html`]) follows RFC 9110 §12.5.1: the
//! weight of a media type is that of the most specific range matching it;
//! HTML is chosen only when `text/html` weighs strictly more than
//! `application/json`, so `*/*`, no `Accept` or a tie keep the JSON answer.
//! Every HTML answer carries a Content-Security-Policy that allows only this
//! origin's script, style and fetches (images also from `blob:` and `data:`).

use axum::http::{HeaderMap, HeaderValue, Method, header};
use axum::response::{IntoResponse, Response};

/// The HTML shell of every page.
const SHELL_HTML: &str = include_str!("page/shell.html");
/// The script of the pages (served as [`SCRIPT_PATH`]).
const APP_JS: &str = include_str!("page/app.js");
/// The style sheet of the pages (served as [`STYLE_PATH`]).
const APP_CSS: &str = include_str!("page/app.css");

/// Path of the pages' script.
pub const SCRIPT_PATH: &str = "/ui/app.js";
/// Path of the pages' style sheet.
pub const STYLE_PATH: &str = "/ui/app.css";

/// Content-Security-Policy of the HTML shell: nothing from another origin,
/// no inline script or style, images also from the object URLs the script
/// makes when it downloads with a token.
const CSP: &str = "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; \
                   connect-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'";

/// The weight (`q`, 0–1) that `accept` gives the media type `ty/subtype`:
/// that of the most specific matching range (`ty/subtype` over `ty/*` over
/// `*/*`), 0 when none matches. A range whose `q` does not parse is skipped.
fn weight(accept: &str, ty: &str, subtype: &str) -> f32 {
    let mut best: Option<(u8, f32)> = None;
    for range in accept.split(',') {
        let mut parts = range.split(';');
        let Some((rt, rs)) = parts.next().and_then(|m| m.trim().split_once('/')) else { continue };
        let specificity = match (rt.trim(), rs.trim()) {
            (t, s) if t.eq_ignore_ascii_case(ty) && s.eq_ignore_ascii_case(subtype) => 3,
            (t, "*") if t.eq_ignore_ascii_case(ty) => 2,
            ("*", "*") => 1,
            _ => continue,
        };
        let q = parts.find_map(|p| p.trim().strip_prefix("q=").or_else(|| p.trim().strip_prefix("Q=")));
        let q = match q.map(str::parse::<f32>) {
            None => 1.0,
            Some(Ok(q)) if (0.0..=1.0).contains(&q) => q,
            Some(_) => continue,
        };
        if best.is_none_or(|(s, _)| specificity > s) {
            best = Some((specificity, q));
        }
    }
    best.map_or(0.0, |(_, q)| q)
}

/// True when the request's `Accept` prefers `text/html` to
/// `application/json` (a browser's navigation); false for `*/*`, no
/// `Accept`, a tie, or JSON first.
pub fn prefers_html(headers: &HeaderMap) -> bool {
    let accept: Vec<&str> = headers.get_all(header::ACCEPT).iter().filter_map(|v| v.to_str().ok()).collect();
    if accept.is_empty() {
        return false;
    }
    let accept = accept.join(",");
    weight(&accept, "text", "html") > weight(&accept, "application", "json")
}

/// True for a path `/v1/jobs/{id}` (one non-empty segment after the prefix).
fn is_job_path(path: &str) -> bool {
    path.strip_prefix("/v1/jobs/").is_some_and(|id| !id.is_empty() && !id.contains('/'))
}

/// True when the request asks for the shell or one of its assets, which are
/// served without a token: `GET`/`HEAD` of `/`, of the script and style
/// sheet, and of a job path whose `Accept` prefers HTML.
pub fn is_public(method: &Method, path: &str, headers: &HeaderMap) -> bool {
    if method != Method::GET && method != Method::HEAD {
        return false;
    }
    matches!(path, "/" | SCRIPT_PATH | STYLE_PATH) || (is_job_path(path) && prefers_html(headers))
}

/// The HTML shell with its security headers and `Vary: accept` (the job
/// path answers JSON to other clients).
pub fn shell() -> Response {
    let mut resp = ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], SHELL_HTML).into_response();
    let h = resp.headers_mut();
    h.insert(header::CONTENT_SECURITY_POLICY, HeaderValue::from_static(CSP));
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    h.insert(header::REFERRER_POLICY, HeaderValue::from_static("no-referrer"));
    h.insert(header::VARY, HeaderValue::from_static("accept"));
    static_headers(resp)
}

/// `nosniff` and `Cache-Control: no-cache` (revalidate, so a new binary's
/// assets are seen at once), shared by the shell and its assets.
fn static_headers(mut resp: Response) -> Response {
    let h = resp.headers_mut();
    h.insert(header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    resp
}

/// `GET /`: the shell, which shows the recent jobs and the upload form.
pub async fn index() -> Response {
    shell()
}

/// `GET /ui/app.js`: the pages' script.
pub async fn script() -> Response {
    static_headers(([(header::CONTENT_TYPE, "text/javascript; charset=utf-8")], APP_JS).into_response())
}

/// `GET /ui/app.css`: the pages' style sheet.
pub async fn style() -> Response {
    static_headers(([(header::CONTENT_TYPE, "text/css; charset=utf-8")], APP_CSS).into_response())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn accept(v: &str) -> HeaderMap {
        let mut h = HeaderMap::new();
        h.insert(header::ACCEPT, HeaderValue::from_str(v).unwrap());
        h
    }

    #[test]
    fn browsers_get_html_and_api_clients_json() {
        let chrome = "text/html,application/xhtml+xml,application/xml;q=0.9,image/avif,image/webp,*/*;q=0.8";
        let firefox = "text/html,application/xhtml+xml,application/xml;q=0.9,*/*;q=0.8";
        for a in [chrome, firefox, "text/html", "text/*", "TEXT/HTML;q=0.5, application/json;q=0.4"] {
            assert!(prefers_html(&accept(a)), "{a}");
        }
        for a in ["*/*", "application/json", "application/json, text/html", "text/html;q=0.5, */*", "text/html;q=x"] {
            assert!(!prefers_html(&accept(a)), "{a}");
        }
        assert!(!prefers_html(&HeaderMap::new()));
    }

    #[test]
    fn the_most_specific_range_gives_the_weight() {
        assert_eq!(weight("text/*;q=0.2, text/html;q=0.7, */*", "text", "html"), 0.7);
        assert_eq!(weight("text/*;q=0.2, */*", "text", "html"), 0.2);
        assert_eq!(weight("image/png", "text", "html"), 0.0);
        assert_eq!(weight("application/json;q=0", "application", "json"), 0.0);
    }

    #[test]
    fn only_the_shell_and_its_assets_are_public() {
        let html = accept("text/html");
        let id = "/v1/jobs/3f2b8c1e-0a4d-4e5f-9b6a-1c2d3e4f5a6b";
        assert!(is_public(&Method::GET, "/", &HeaderMap::new()));
        assert!(is_public(&Method::GET, SCRIPT_PATH, &HeaderMap::new()));
        assert!(is_public(&Method::HEAD, STYLE_PATH, &HeaderMap::new()));
        assert!(is_public(&Method::GET, id, &html));
        assert!(!is_public(&Method::GET, id, &accept("*/*")));
        assert!(!is_public(&Method::DELETE, id, &html));
        assert!(!is_public(&Method::GET, &format!("{id}/artifacts/report.json"), &html));
        assert!(!is_public(&Method::GET, "/v1/jobs", &html));
        assert!(!is_public(&Method::GET, "/ui/other.js", &html));
    }

    #[test]
    fn the_shell_names_only_its_own_assets() {
        assert!(SHELL_HTML.contains(SCRIPT_PATH) && SHELL_HTML.contains(STYLE_PATH));
        for text in [SHELL_HTML, APP_JS, APP_CSS] {
            assert!(!text.contains("http://") && !text.contains("https://"), "an external URL in the pages");
        }
        assert!(!APP_JS.contains("innerHTML"), "the script builds the DOM with createElement/textContent");
    }
}
