//! The web front's access rule (`scanner_web::front::Access::admit`) on any request parts: the
//! method, a `Host`, an `Origin`, an upgrade, a token header and a query, each from the fuzzer's
//! bytes; an answer, never a panic, and never an admission for a host that is not ours.
#![no_main]
use libfuzzer_sys::fuzz_target;
use scanner_web::front::{Access, AccessRefusal};

fuzz_target!(|data: &[u8]| {
    let mut parts = data.split(|&b| b == 0);
    let mut next = || parts.next().unwrap_or_default();
    let (method, host, origin, token, query, upgrade) =
        (next(), next(), next(), next(), next(), next());
    let method = axum::http::Method::from_bytes(method).unwrap_or(axum::http::Method::GET);
    let mut headers = axum::http::HeaderMap::new();
    for (name, value) in [
        ("host", host),
        ("origin", origin),
        ("x-scanner-token", token),
        ("upgrade", upgrade),
    ] {
        if let Ok(v) = axum::http::HeaderValue::from_bytes(value) {
            if !value.is_empty() {
                headers.insert(name, v);
            }
        }
    }
    let query = std::str::from_utf8(query).ok();
    for bound in ["127.0.0.1:8090", "0.0.0.0:8090"] {
        let access = Access::new(bound.parse().unwrap(), &["scanner.local".to_string()]).unwrap();
        let local = std::net::IpAddr::from([192, 168, 1, 5]);
        if access.admit(&method, &headers, query, local).is_ok() {
            let name = std::str::from_utf8(host).unwrap_or("").to_ascii_lowercase();
            let name = name.rsplit_once(':').map_or(name.as_str(), |(n, _)| n);
            let ours = name == "localhost"
                || name == "scanner.local"
                || name == "192.168.1.5"
                || name.trim_matches(['[', ']']).parse::<std::net::IpAddr>().is_ok_and(|ip| ip.is_loopback());
            assert!(ours, "admitted a foreign host: {host:?}");
        }
        let _ = AccessRefusal::ForeignHost.kind();
    }
});
