//! Class names of closed-vocabulary models and the mapping from what a
//! person says to those classes (exact, plural, synonyms).

/// Synonyms: what a person may say → COCO class name.
const SYNONYMS: &[(&str, &str)] = &[
    ("sofa", "couch"),
    ("settee", "couch"),
    ("table", "dining table"),
    ("desk", "dining table"),
    ("dinner table", "dining table"),
    ("tv", "tv"),
    ("television", "tv"),
    ("monitor", "tv"),
    ("screen", "tv"),
    ("people", "person"),
    ("man", "person"),
    ("men", "person"),
    ("woman", "person"),
    ("women", "person"),
    ("child", "person"),
    ("children", "person"),
    ("kid", "person"),
    ("human", "person"),
    ("pedestrian", "person"),
    ("plant", "potted plant"),
    ("houseplant", "potted plant"),
    ("fridge", "refrigerator"),
    ("phone", "cell phone"),
    ("mobile phone", "cell phone"),
    ("mobile", "cell phone"),
    ("smartphone", "cell phone"),
    ("laptop computer", "laptop"),
    ("computer", "laptop"),
    ("notebook", "laptop"),
    ("mug", "cup"),
    ("glass", "wine glass"),
    ("bike", "bicycle"),
    ("motorbike", "motorcycle"),
    ("toilet seat", "toilet"),
    ("wc", "toilet"),
    ("armchair", "chair"),
    ("seat", "chair"),
    ("stool", "chair"),
    ("puppy", "dog"),
    ("kitten", "cat"),
    ("handbag", "handbag"),
    ("purse", "handbag"),
    ("bag", "handbag"),
    ("rucksack", "backpack"),
    ("remote control", "remote"),
    ("hairdryer", "hair drier"),
    ("hair dryer", "hair drier"),
    ("ball", "sports ball"),
    ("teddy", "teddy bear"),
    ("microwave oven", "microwave"),
];

/// Parses the `names` metadata of an Ultralytics export: a Python dict
/// literal (`{0: 'person', 1: 'bicycle'}`) or a JSON list/object. Returns
/// names in index order, or an error naming what was wrong.
pub fn parse_class_names(text: &str) -> Result<Vec<String>, String> {
    let t = text.trim();
    if let Ok(list) = serde_json::from_str::<Vec<String>>(t) {
        return Ok(list);
    }
    let inner = t
        .strip_prefix('{')
        .and_then(|s| s.strip_suffix('}'))
        .ok_or_else(|| format!("`names` is neither a list nor a dict: {}", head(t)))?;
    let mut entries: Vec<(usize, String)> = Vec::new();
    let mut rest = inner.trim();
    while !rest.is_empty() {
        let (key, after) = rest
            .split_once(':')
            .ok_or_else(|| format!("`names`: expected `index: 'name'` at {}", head(rest)))?;
        let key = key.trim().trim_matches(|c| c == '"' || c == '\'');
        let idx: usize = key
            .parse()
            .map_err(|_| format!("`names`: class index `{key}` is not a number"))?;
        let after = after.trim_start();
        let quote = after
            .chars()
            .next()
            .filter(|c| *c == '\'' || *c == '"')
            .ok_or_else(|| format!("`names`: class {idx} has no quoted name"))?;
        let body = &after[1..];
        let end = body
            .find(quote)
            .ok_or_else(|| format!("`names`: class {idx}: unterminated name"))?;
        entries.push((idx, body[..end].to_string()));
        rest = body[end + 1..].trim_start();
        rest = rest.strip_prefix(',').unwrap_or(rest).trim_start();
    }
    entries.sort_by_key(|(i, _)| *i);
    for (expect, (i, _)) in entries.iter().enumerate() {
        if *i != expect {
            return Err(format!(
                "`names`: class indices are not 0..{} (missing {expect})",
                entries.len()
            ));
        }
    }
    if entries.is_empty() {
        return Err("`names` is empty".into());
    }
    Ok(entries.into_iter().map(|(_, n)| n).collect())
}

fn head(s: &str) -> String {
    s.chars().take(40).collect()
}

/// The class a prompt means among `names`: exact (case-insensitive), then
/// singular of a plural, then the synonym table.
pub fn resolve_prompt(prompt: &str, names: &[String]) -> Option<usize> {
    let p = prompt.trim().to_lowercase();
    let find = |q: &str| names.iter().position(|n| n.eq_ignore_ascii_case(q));
    if let Some(i) = find(&p) {
        return Some(i);
    }
    for s in singulars(&p) {
        if let Some(i) = find(&s) {
            return Some(i);
        }
    }
    for cand in std::iter::once(p.clone()).chain(singulars(&p)) {
        if let Some((_, target)) = SYNONYMS.iter().find(|(k, _)| *k == cand) {
            if let Some(i) = find(target) {
                return Some(i);
            }
        }
    }
    None
}

fn singulars(p: &str) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(s) = p.strip_suffix("ies") {
        out.push(format!("{s}y"));
    }
    if let Some(s) = p.strip_suffix("es") {
        out.push(s.to_string());
    }
    if let Some(s) = p.strip_suffix('s') {
        out.push(s.to_string());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coco() -> Vec<String> {
        [
            "person",
            "bicycle",
            "bus",
            "couch",
            "dining table",
            "tv",
            "bench",
            "potted plant",
            "cup",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    }

    #[test]
    fn python_dict_literal_and_json_list() {
        let n = parse_class_names("{0: 'person', 1: \"bicycle\", 2: 'teddy bear'}").unwrap();
        assert_eq!(n, vec!["person", "bicycle", "teddy bear"]);
        let n = parse_class_names("[\"a\", \"b\"]").unwrap();
        assert_eq!(n, vec!["a", "b"]);
        assert!(parse_class_names("{0: 'a', 2: 'c'}")
            .unwrap_err()
            .contains("missing 1"));
        assert!(parse_class_names("garbage").is_err());
        assert!(parse_class_names("{0: person}").is_err());
    }

    #[test]
    fn prompts_resolve_exact_plural_and_synonyms() {
        let n = coco();
        assert_eq!(resolve_prompt("Person", &n), Some(0));
        assert_eq!(resolve_prompt("buses", &n), Some(2));
        assert_eq!(resolve_prompt("benches", &n), Some(6));
        assert_eq!(resolve_prompt("cups", &n), Some(8));
        assert_eq!(resolve_prompt("sofa", &n), Some(3));
        assert_eq!(resolve_prompt("sofas", &n), Some(3));
        assert_eq!(resolve_prompt("table", &n), Some(4));
        assert_eq!(resolve_prompt("monitor", &n), Some(5));
        assert_eq!(resolve_prompt("screen", &n), Some(5));
        assert_eq!(resolve_prompt("people", &n), Some(0));
        assert_eq!(resolve_prompt("woman", &n), Some(0));
        assert_eq!(resolve_prompt("plant", &n), Some(7));
        assert_eq!(resolve_prompt("door handle", &n), None);
    }
}
