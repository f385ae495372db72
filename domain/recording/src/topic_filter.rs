//! Which topics a tool works on: glob include/exclude patterns and catalogue layers.
//!
//! Patterns: `*` matches any run of characters (including `/`), `?` one character, everything
//! else itself: `arm*` selects `arm1/state` and `arm2/command`, `*/state` every state channel.

use harvest_ipc::catalogue::Layer;

/// True when `topic` matches the glob `pattern` (see the module docs).
pub fn glob_matches(pattern: &str, topic: &str) -> bool {
    let pattern: Vec<char> = pattern.chars().collect();
    let topic: Vec<char> = topic.chars().collect();
    // Iterative matcher with single backtrack point for the last `*` (linear in practice).
    let (mut p, mut t) = (0usize, 0usize);
    let mut star: Option<(usize, usize)> = None;
    while t < topic.len() {
        if p < pattern.len() && pattern[p] == '*' {
            star = Some((p, t));
            p += 1;
        } else if p < pattern.len() && (pattern[p] == '?' || pattern[p] == topic[t]) {
            p += 1;
            t += 1;
        } else if let Some((star_p, star_t)) = star {
            p = star_p + 1;
            t = star_t + 1;
            star = Some((star_p, star_t + 1));
        } else {
            return false;
        }
    }
    while p < pattern.len() && pattern[p] == '*' {
        p += 1;
    }
    p == pattern.len()
}

/// Include/exclude patterns plus the catalogue layers to consider.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct TopicFilter {
    /// A topic must match one of these (all topics when empty).
    pub include: Vec<String>,
    /// A topic matching one of these is left out, even if included.
    pub exclude: Vec<String>,
    /// Layers considered for catalogue channels (see [`Layer`]); empty = every layer.
    pub layers: Vec<Layer>,
}

impl TopicFilter {
    /// Selects topics by pattern only (any layer).
    pub fn patterns(include: &[String], exclude: &[String]) -> Self {
        Self {
            include: include.to_vec(),
            exclude: exclude.to_vec(),
            layers: Vec::new(),
        }
    }

    /// True when `topic` passes the include and exclude patterns.
    pub fn matches_topic(&self, topic: &str) -> bool {
        let included =
            self.include.is_empty() || self.include.iter().any(|p| glob_matches(p, topic));
        included && !self.exclude.iter().any(|p| glob_matches(p, topic))
    }

    /// True when a catalogue channel of `layer` named `topic` is selected.
    pub fn selects(&self, topic: &str, layer: Layer) -> bool {
        (self.layers.is_empty() || self.layers.contains(&layer)) && self.matches_topic(topic)
    }

    /// Include patterns that match none of `topics` (to warn about typos).
    pub fn unmatched_includes<'a>(&'a self, topics: &[&str]) -> Vec<&'a str> {
        self.include
            .iter()
            .filter(|pattern| !topics.iter().any(|topic| glob_matches(pattern, topic)))
            .map(String::as_str)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glob_semantics() {
        assert!(glob_matches("*", "camera/rgbd"));
        assert!(glob_matches("camera/*", "camera/rgbd"));
        assert!(glob_matches("arm*", "arm1/state"));
        assert!(glob_matches("*/state", "vacuum/state"));
        assert!(glob_matches("arm?/state", "arm2/state"));
        assert!(glob_matches("hw/*", "hw/camera/rgbd"));
        assert!(glob_matches("a*b*c", "axxbyyc"));
        assert!(!glob_matches("a*b*c", "axxbyy"));
        assert!(!glob_matches("camera", "camera/rgbd"));
        assert!(!glob_matches("arm?/state", "arm10/state"));
        assert!(glob_matches("", ""));
        assert!(!glob_matches("", "x"));
    }

    #[test]
    fn include_exclude_and_layers() {
        let filter = TopicFilter {
            include: vec!["arm*".into(), "camera/*".into()],
            exclude: vec!["*/command".into()],
            layers: vec![Layer::Stack],
        };
        assert!(filter.selects("arm1/state", Layer::Stack));
        assert!(!filter.selects("arm1/command", Layer::Stack));
        assert!(filter.selects("camera/rgbd", Layer::Stack));
        assert!(!filter.selects("camera/rgbd", Layer::Hardware));
        assert!(!filter.selects("vacuum/state", Layer::Stack));
        assert_eq!(filter.unmatched_includes(&["arm1/state"]), vec!["camera/*"]);
        let everything = TopicFilter::default();
        assert!(everything.selects("hw/camera/rgbd", Layer::Hardware));
    }
}
