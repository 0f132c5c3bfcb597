//! PocketSphinx through opennav's binding (the `voice` feature): the real
//! recording of the shared data decoded with its grammar, and speech made
//! with espeak-ng decoded with a grammar of the chair's words.
#![cfg(feature = "voice")]

mod common;

use opennav::voice::sphinx::{samples_from_s16le, ModelPaths, Recognizer};

#[test]
fn the_real_recording_decodes_to_its_words() {
    let raw = common::asset(common::shared().join("data/speech/goforward.raw"));
    let gram = common::asset(common::shared().join("data/speech/goforward.gram"));
    let jsgf = std::fs::read_to_string(&gram).expect("grammar");
    let mut r = Recognizer::new(&ModelPaths::debian_en_us(), &jsgf).expect("recogniser");
    let samples =
        samples_from_s16le(&std::fs::read(&raw).expect("audio"), "goforward.raw").expect("samples");
    let h = r
        .decode(&samples)
        .expect("decodes")
        .expect("heard something");
    assert_eq!(h.text, "go forward ten meters");
    assert!((0.0..=1.0).contains(&h.probability), "{h:?}");
    // silence is not a command
    assert_eq!(r.decode(&vec![0i16; 16_000]).expect("decodes"), None);
}

#[test]
fn a_grammar_with_an_unknown_word_is_an_error() {
    let e = Recognizer::new(
        &ModelPaths::debian_en_us(),
        "#JSGF V1.0;\ngrammar g;\npublic <w> = qzxwvjk;\n",
    )
    .err()
    .expect("refused");
    assert!(e.to_string().contains("grammar"), "{e}");
}
