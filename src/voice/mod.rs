//! Speech recognition on the chair's laptop, offline: PocketSphinx
//! (Debian's 0.8 libraries, the `voice` feature) with a JSGF grammar.

pub mod sphinx;
