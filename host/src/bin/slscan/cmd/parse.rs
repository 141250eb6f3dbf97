//! Parsers of option values that several subcommands share.

/// `WIDTHxHEIGHT` (or `WIDTHXHEIGHT`) as two positive integers.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("{s:?} is not WIDTHxHEIGHT"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| *n > 0)
            .ok_or_else(|| format!("{v:?} in {s:?} is not a positive integer"))
    };
    Ok((parse(w)?, parse(h)?))
}
