//! No stringly errors in product code: every `Result` whose error is a `String` (or `&str`), and
//! every `Box<dyn Error>`, in the workspace's sources and examples is a failure here. A caller
//! cannot tell one failure from another by a sentence; an error is a small type with `Display`
//! (`anyhow` is for `main` only, where nobody matches on the error any more).
//!
//! Read: each member crate's `src/` and `examples/` (and the workspace test crate's `examples/`),
//! parsed with `syn`; items and modules under `#[cfg(test)]` or `#[test]` are skipped. Type
//! aliases, closures' return types and trait objects are seen because every type anywhere is
//! visited.

use std::path::{Path, PathBuf};

use syn::visit::Visit;

/// The workspace's member folders, from its manifest.
fn members(root: &Path) -> Vec<PathBuf> {
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let list = manifest
        .split("members = [")
        .nth(1)
        .and_then(|s| s.split(']').next())
        .expect("the workspace's members");
    let out: Vec<PathBuf> = list
        .split(',')
        .map(|m| m.trim().trim_matches('"'))
        .filter(|m| !m.is_empty())
        .map(|m| root.join(m))
        .collect();
    assert!(out.len() >= 8, "found only {out:?}");
    out
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The files to read: `src/` and `examples/` of every member, not those of a member nested in
/// another (each is read once, as itself).
fn product_files(root: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for m in members(root) {
        for sub in ["src", "examples"] {
            rust_files(&m.join(sub), &mut out);
        }
    }
    out.sort();
    out.dedup();
    out
}

fn is_test_only(attrs: &[syn::Attribute]) -> bool {
    attrs.iter().any(|a| {
        let p = a.path();
        if p.is_ident("test") {
            return true;
        }
        if p.is_ident("cfg") {
            let mut test = false;
            let _ = a.parse_nested_meta(|m| {
                test |= m.path.is_ident("test");
                Ok(())
            });
            return test;
        }
        false
    })
}

/// The last segment's name of a path type (`std::string::String` → `String`).
fn last_name(ty: &syn::Type) -> Option<String> {
    match ty {
        syn::Type::Path(p) => p.path.segments.last().map(|s| s.ident.to_string()),
        syn::Type::Reference(r) => last_name(&r.elem).map(|n| format!("&{n}")),
        _ => None,
    }
}

/// Whether a trait object names an `Error` trait (`dyn Error`, `dyn std::error::Error + Send`).
fn is_dyn_error(ty: &syn::Type) -> bool {
    let syn::Type::TraitObject(t) = ty else {
        return false;
    };
    t.bounds.iter().any(|b| match b {
        syn::TypeParamBound::Trait(tb) => {
            tb.path.segments.last().is_some_and(|s| s.ident == "Error")
        }
        _ => false,
    })
}

struct Walk<'a> {
    file: &'a Path,
    /// The item being read (a function, a type alias, a struct), named in the report.
    item: String,
    found: Vec<String>,
}

impl Walk<'_> {
    fn here(&mut self, what: &str) {
        self.found.push(format!(
            "{}: {what} in `{}`",
            self.file.display(),
            self.item
        ));
    }
}

impl<'ast> Visit<'ast> for Walk<'_> {
    fn visit_item(&mut self, i: &'ast syn::Item) {
        let attrs: &[syn::Attribute] = match i {
            syn::Item::Fn(f) => &f.attrs,
            syn::Item::Mod(m) => &m.attrs,
            syn::Item::Impl(m) => &m.attrs,
            syn::Item::Struct(m) => &m.attrs,
            syn::Item::Enum(m) => &m.attrs,
            syn::Item::Type(m) => &m.attrs,
            syn::Item::Const(m) => &m.attrs,
            syn::Item::Static(m) => &m.attrs,
            syn::Item::Trait(m) => &m.attrs,
            syn::Item::Use(m) => &m.attrs,
            _ => &[],
        };
        if is_test_only(attrs) {
            return;
        }
        let before = self.item.clone();
        match i {
            syn::Item::Fn(f) => self.item = format!("fn {}", f.sig.ident),
            syn::Item::Type(t) => self.item = format!("type {}", t.ident),
            syn::Item::Struct(t) => self.item = format!("struct {}", t.ident),
            syn::Item::Enum(t) => self.item = format!("enum {}", t.ident),
            syn::Item::Trait(t) => self.item = format!("trait {}", t.ident),
            syn::Item::Mod(t) => self.item = format!("mod {}", t.ident),
            _ => {}
        }
        syn::visit::visit_item(self, i);
        self.item = before;
    }

    fn visit_impl_item_fn(&mut self, f: &'ast syn::ImplItemFn) {
        if is_test_only(&f.attrs) {
            return;
        }
        let before = std::mem::replace(&mut self.item, format!("fn {}", f.sig.ident));
        syn::visit::visit_impl_item_fn(self, f);
        self.item = before;
    }

    fn visit_trait_item_fn(&mut self, f: &'ast syn::TraitItemFn) {
        let before = std::mem::replace(&mut self.item, format!("fn {}", f.sig.ident));
        syn::visit::visit_trait_item_fn(self, f);
        self.item = before;
    }

    fn visit_type_path(&mut self, p: &'ast syn::TypePath) {
        if let Some(seg) = p.path.segments.last()
            && seg.ident == "Result"
            && let syn::PathArguments::AngleBracketed(args) = &seg.arguments
        {
            let types: Vec<&syn::Type> = args
                .args
                .iter()
                .filter_map(|a| match a {
                    syn::GenericArgument::Type(t) => Some(t),
                    _ => None,
                })
                .collect();
            if types.len() == 2 {
                match last_name(types[1]).as_deref() {
                    Some("String") | Some("&str") => self.here("Result<_, String>"),
                    _ => {}
                }
            }
        }
        if let Some(seg) = p.path.segments.last()
            && seg.ident == "Box"
            && let syn::PathArguments::AngleBracketed(args) = &seg.arguments
            && args
                .args
                .iter()
                .any(|a| matches!(a, syn::GenericArgument::Type(t) if is_dyn_error(t)))
        {
            self.here("Box<dyn Error>");
        }
        syn::visit::visit_type_path(self, p);
    }
}

#[test]
fn no_result_with_a_string_error_or_boxed_dyn_error_in_product_code() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let files = product_files(root);
    assert!(files.len() > 100, "read only {} files", files.len());
    let mut found = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let parsed =
            syn::parse_file(&text).unwrap_or_else(|e| panic!("{}: not parsed: {e}", f.display()));
        let rel = f.strip_prefix(root).unwrap();
        let mut w = Walk {
            file: rel,
            item: String::from("the file"),
            found: Vec::new(),
        };
        if is_test_only(&parsed.attrs) {
            continue;
        }
        w.visit_file(&parsed);
        found.extend(w.found);
    }
    assert!(
        found.is_empty(),
        "{} stringly error type(s) in product code (give each boundary a small error type):\n{}",
        found.len(),
        found.join("\n")
    );
}

/// The check finds what it is for: a stringly function, a type alias, a closure and a boxed
/// error are each seen; test code is not.
#[test]
fn the_check_sees_each_form() {
    let src = r#"
        fn a() -> Result<(), String> { Ok(()) }
        type B = std::result::Result<u8, std::string::String>;
        fn c() { let _f = |x: u8| -> Result<u8, &'static str> { Ok(x) }; }
        fn d() -> Result<(), Box<dyn std::error::Error + Send>> { Ok(()) }
        fn fine() -> Result<(), std::io::Error> { Ok(()) }
        #[cfg(test)]
        mod tests { fn t() -> Result<(), String> { Ok(()) } }
    "#;
    let parsed = syn::parse_file(src).unwrap();
    let mut w = Walk {
        file: Path::new("x.rs"),
        item: String::new(),
        found: Vec::new(),
    };
    w.visit_file(&parsed);
    let found = w.found;
    assert_eq!(found.len(), 4, "{found:?}");
    for name in ["fn a", "type B", "fn c", "fn d"] {
        assert!(
            found.iter().any(|f| f.contains(&format!("`{name}`"))),
            "{name} in {found:?}"
        );
    }
}
