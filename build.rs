//! Links PocketSphinx (Debian 12: libpocketsphinx-dev, libsphinxbase-dev)
//! when the `voice` feature is on.
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var_os("CARGO_FEATURE_VOICE").is_some() {
        println!("cargo:rustc-link-lib=pocketsphinx");
        println!("cargo:rustc-link-lib=sphinxbase");
    }
}
