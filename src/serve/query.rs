//! The query string of an API request: decoded parameters, each at most once, read as the
//! endpoint's types with errors that name the parameter.

/// Query parameters: decoded, each at most once.
pub struct Query(Vec<(String, String)>);

impl Query {
    pub fn parse(text: &str) -> Result<Query, String> {
        let mut pairs: Vec<(String, String)> = Vec::new();
        for part in text.split('&').filter(|p| !p.is_empty()) {
            let (k, v) = part.split_once('=').unwrap_or((part, ""));
            let (k, v) = (percent_decode(k)?, percent_decode(v)?);
            if pairs.iter().any(|(p, _)| *p == k) {
                return Err(format!("parameter {k} given twice"));
            }
            pairs.push((k, v));
        }
        Ok(Query(pairs))
    }

    pub fn get(&self, key: &str) -> Option<&str> {
        self.0
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Refuse parameters the endpoint does not know (a typo would otherwise be ignored).
    pub(super) fn only(&self, known: &[&str]) -> Result<(), (u16, String)> {
        match self.0.iter().find(|(k, _)| !known.contains(&k.as_str())) {
            Some((k, _)) if known.is_empty() => Err((
                400,
                format!("unknown parameter {k:?}: this takes no parameters"),
            )),
            Some((k, _)) => Err((
                400,
                format!("unknown parameter {k:?} (known: {})", known.join(", ")),
            )),
            None => Ok(()),
        }
    }

    pub(super) fn u64_in(&self, key: &str, lo: u64, hi: u64) -> Result<Option<u64>, (u16, String)> {
        self.get(key)
            .map(|t| match t.trim().parse::<u64>() {
                Ok(v) if (lo..=hi).contains(&v) => Ok(v),
                _ => Err((
                    400,
                    format!("invalid {key} {t:?}: must be an integer in {lo}..={hi}"),
                )),
            })
            .transpose()
    }

    pub(super) fn f64_in(&self, key: &str, lo: f64, hi: f64) -> Result<Option<f64>, (u16, String)> {
        self.get(key)
            .map(|t| match t.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && (lo..=hi).contains(&v) => Ok(v),
                _ => Err((
                    400,
                    format!("invalid {key} {t:?}: must be a finite number in [{lo}, {hi}]"),
                )),
            })
            .transpose()
    }

    pub(super) fn bool(&self, key: &str) -> Result<bool, (u16, String)> {
        match self.get(key) {
            None | Some("0") | Some("false") => Ok(false),
            Some("1") | Some("true") | Some("") => Ok(true),
            Some(t) => Err((400, format!("invalid {key} {t:?}: 0/1 or true/false"))),
        }
    }

    pub(super) fn triple(&self, key: &str) -> Result<Option<[f64; 3]>, (u16, String)> {
        let Some(t) = self.get(key) else {
            return Ok(None);
        };
        let v: Vec<f64> = t
            .split(',')
            .filter_map(|c| c.trim().parse::<f64>().ok())
            .collect();
        if v.len() != 3 || t.split(',').count() != 3 || v.iter().any(|c| !c.is_finite()) {
            return Err((
                400,
                format!("invalid {key} {t:?}: expected three finite numbers A,B,C"),
            ));
        }
        Ok(Some([v[0], v[1], v[2]]))
    }
}

fn percent_decode(text: &str) -> Result<String, String> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'%' => {
                let hex = bytes
                    .get(i + 1..i + 3)
                    .and_then(|h| std::str::from_utf8(h).ok())
                    .and_then(|h| u8::from_str_radix(h, 16).ok())
                    .ok_or_else(|| format!("bad percent-encoding in {text:?}"))?;
                out.push(hex);
                i += 3;
            }
            b'+' => {
                out.push(b' ');
                i += 1;
            }
            b => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8(out).map_err(|_| format!("query is not UTF-8: {text:?}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queries_decode_and_refuse_repeats_and_garbage() {
        let q = Query::parse("origin=1%2C2,3&normal=0,0,1&size=64").unwrap();
        assert_eq!(q.triple("origin").unwrap(), Some([1.0, 2.0, 3.0]));
        assert_eq!(q.u64_in("size", 1, 512).unwrap(), Some(64));
        assert!(q.u64_in("size", 1, 32).is_err());
        assert!(Query::parse("a=1&a=2").is_err());
        assert!(Query::parse("a=%zz").is_err());
        for bad in ["1,2", "1,2,3,4", "1,nan,3", "1,inf,2", "a,b,c", "1,,2"] {
            let q = Query::parse(&format!("origin={bad}")).unwrap();
            assert!(q.triple("origin").is_err(), "{bad}");
        }
        assert!(q.only(&["origin"]).is_err());
        assert!(q.only(&["origin", "normal", "size"]).is_ok());
    }
}
