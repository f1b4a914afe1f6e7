//! Number formats shared by the terminal table, the explanations and the HTML report, so that
//! a change reads the same everywhere.

/// A relative change of a residual (`new / old − 1`; positive = worse) as a signed percentage
/// with `decimals` decimals (`−45.2 %`, `+12.0 %`); from ten times the residual on (`+900 %`)
/// as a factor (`×4.55e5`), which reads better than `+45461247 %`. `n/a` for a non-finite
/// change.
pub fn change_percent(change: f64, decimals: usize) -> String {
    if !change.is_finite() {
        "n/a".to_string()
    } else if change < 9.0 {
        format!("{:+.decimals$} %", 100.0 * change)
    } else {
        format!("×{}", significant(1.0 + change, 3))
    }
}

/// `x` with `digits` significant digits: plain below 10 000 (`0.0123`, `1.5`, `4550`),
/// exponent notation above (`4.55e5`).
pub fn significant(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return "n/a".to_string();
    }
    if x == 0.0 {
        return "0".to_string();
    }
    let mag = x.abs().log10().floor() as i32;
    if !(-4..4).contains(&mag) {
        let s = format!("{:.*e}", digits.saturating_sub(1), x);
        // `4.550e5` → `4.55e5`: trim trailing zeros of the mantissa.
        match s.split_once('e') {
            Some((m, e)) if m.contains('.') => {
                format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
            }
            _ => s,
        }
    } else {
        let decimals = (digits as i32 - 1 - mag).max(0) as usize;
        format!("{x:.decimals$}")
    }
}

/// An optional percentage for a table column (`n/a` when undefined), `width` wide, with
/// three significant digits (`0.0123`, `1.23`, `98.7`).
pub fn percent_cell(p: Option<f64>, width: usize) -> String {
    let text = p.map_or_else(
        || "n/a".to_string(),
        |x| {
            if x.abs() >= 100.0 {
                format!("{x:.0}")
            } else {
                significant(x, 3)
            }
        },
    );
    format!("{text:>width$}")
}

/// The characters a command-line argument may hold and still be printed without quotes: a
/// POSIX shell gives none of them a meaning (`[A-Za-z0-9_./=,:@%+-]`).
pub fn is_shell_safe(c: char) -> bool {
    c.is_ascii_alphanumeric() || "_./=,:@%+-".contains(c)
}

/// One argument as a POSIX shell reads it back unchanged: as it is when made only of
/// [`is_shell_safe`] characters (and not empty), otherwise in single quotes, each `'` written
/// `'\''`. Nothing inside single quotes is expanded: `;`, `$(…)`, backticks, spaces and
/// newlines stay text.
pub fn shell_quote(arg: &str) -> std::borrow::Cow<'_, str> {
    if !arg.is_empty() && arg.chars().all(is_shell_safe) {
        std::borrow::Cow::Borrowed(arg)
    } else {
        std::borrow::Cow::Owned(format!("'{}'", arg.replace('\'', r"'\''")))
    }
}

/// A command line from its arguments, each quoted by [`shell_quote`] and separated by one
/// space: safe to paste into a POSIX shell, which splits it back into the same arguments.
pub fn shell_join<S: AsRef<str>>(args: impl IntoIterator<Item = S>) -> String {
    args.into_iter()
        .map(|a| shell_quote(a.as_ref()).into_owned())
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn changes_read_as_percentages_then_factors() {
        assert_eq!(change_percent(-0.452, 1), "-45.2 %");
        assert_eq!(change_percent(-0.452, 0), "-45 %");
        assert_eq!(change_percent(0.12, 1), "+12.0 %");
        assert_eq!(change_percent(8.5, 1), "+850.0 %");
        assert_eq!(change_percent(14.36, 1), "×15.4");
        // The issue's case: +45 461 247 % is 454 613 times the residual.
        assert_eq!(change_percent(454_612.47, 0), "×4.55e5");
        assert_eq!(change_percent(f64::NAN, 1), "n/a");
    }

    #[test]
    fn significant_digits() {
        assert_eq!(significant(0.012345, 3), "0.0123");
        assert_eq!(significant(1.5, 3), "1.50");
        assert_eq!(significant(98.76, 3), "98.8");
        assert_eq!(significant(4550.0, 3), "4550");
        assert_eq!(significant(45_500.0, 3), "4.55e4");
        assert_eq!(significant(2.0e-6, 3), "2e-6");
        assert_eq!(percent_cell(None, 6), "   n/a");
        assert_eq!(percent_cell(Some(123.4), 6), "   123");
    }
}
