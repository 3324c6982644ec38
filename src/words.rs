//! The words of a fieldless enum in scenario files and on the command line:
//! its [`FromStr`](std::str::FromStr) from one table, with one wording of
//! the error (a leaf: it imports nothing of the crate).

/// The words as `"a, b or c"` (`"a"` alone, `"a or b"` for two).
pub(crate) fn one_of(words: &[&str]) -> String {
    match words.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        Some((last, _)) => last.to_string(),
        None => String::new(),
    }
}

/// `FromStr` (`Err = String`) for a fieldless enum from the table of its
/// words: `from_words!(Type, "what", "word" => Variant, …)`. Another word
/// is the error `unknown what 'word' (expected a, b or c)`, the words in
/// the table's order.
macro_rules! from_words {
    ($ty:ty, $what:literal, $($word:literal => $variant:ident),+ $(,)?) => {
        impl std::str::FromStr for $ty {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                match s {
                    $($word => Ok(Self::$variant),)+
                    other => Err(format!(
                        "unknown {} '{other}' (expected {})",
                        $what,
                        $crate::words::one_of(&[$($word),+])
                    )),
                }
            }
        }
    };
}
pub(crate) use from_words;

#[cfg(test)]
mod tests {
    /// A test enum with the table's words.
    #[derive(Debug, PartialEq)]
    enum Fruit {
        Apple,
        BloodOrange,
        Pear,
    }
    from_words!(Fruit, "fruit", "apple" => Apple, "blood_orange" => BloodOrange, "pear" => Pear);

    /// Each word parses to its variant; another word names what was
    /// expected, in the table's order, and the lists of one and two words
    /// read as English.
    #[test]
    fn words_parse_and_an_unknown_word_lists_them() {
        assert_eq!("apple".parse::<Fruit>(), Ok(Fruit::Apple));
        assert_eq!("blood_orange".parse::<Fruit>(), Ok(Fruit::BloodOrange));
        assert_eq!("pear".parse::<Fruit>(), Ok(Fruit::Pear));
        assert_eq!(
            "Apple".parse::<Fruit>(),
            Err("unknown fruit 'Apple' (expected apple, blood_orange or pear)".to_string())
        );
        assert_eq!(super::one_of(&["a"]), "a");
        assert_eq!(super::one_of(&["a", "b"]), "a or b");
        assert_eq!(super::one_of(&[]), "");
    }
}
