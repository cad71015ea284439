//! Where a headset on the same network reaches this machine: the addresses and names the web
//! viewer's certificate holds, and the URLs `snerf serve` prints and puts in its QR code.
//!
//! Why every interface address and the host name: a headset scanning the QR code, or a person
//! typing the address, opens the page by one of them, and the browser checks that name
//! against the certificate's subject alternative names before the one-time warning can be
//! clicked through (and before WebTransport's pinned hash is even tried). Loopback is never
//! the URL a headset gets: on the headset it names the headset.

use std::net::{IpAddr, SocketAddr};

/// The machine's names as seen from the network.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LocalNames {
    /// Non-loopback interface addresses, IPv4 first (a headset on Wi-Fi almost always has
    /// one), then global and unique-local IPv6. Link-local IPv6 is left out: a URL needs a
    /// zone id there, which browsers do not accept.
    pub addrs: Vec<IpAddr>,
    /// The host name (`gethostname`), when it is a valid DNS name.
    pub hostname: Option<String>,
}

impl LocalNames {
    /// This machine's interfaces and host name, as reachable through a socket bound to
    /// `bind`: an unspecified IPv4 address reaches every IPv4 interface, an unspecified IPv6
    /// one (dual stack) every interface, a specific address only itself.
    pub fn of_this_machine(bind: IpAddr) -> LocalNames {
        let ifaces: Vec<IpAddr> = if_addrs::get_if_addrs()
            .map(|v| v.into_iter().map(|i| i.ip()).collect())
            .unwrap_or_default();
        let hostname = gethostname::gethostname().to_str().map(str::to_string).filter(|h| dns_name_ok(h));
        LocalNames { addrs: reachable(bind, &ifaces), hostname }
    }

    /// Every name the certificate must hold: loopback names (a browser on this machine),
    /// every LAN address, the host name and `hostname.local` (mDNS, which Quest and Apple
    /// headsets resolve).
    pub fn cert_names(&self) -> Vec<String> {
        let mut n = vec!["localhost".to_string(), "127.0.0.1".into(), "::1".into()];
        n.extend(self.addrs.iter().map(|a| a.to_string()));
        if let Some(h) = &self.hostname {
            n.push(h.clone());
            if !h.ends_with(".local") {
                n.push(format!("{h}.local"));
            }
        }
        n.dedup();
        n
    }

    /// The page's URL on each LAN address (`https://ADDR:PORT/`), in `addrs` order. Empty
    /// when the socket reaches no LAN interface (bound to loopback, or no network).
    pub fn urls(&self, port: u16) -> Vec<String> {
        self.addrs.iter().map(|a| page_url(SocketAddr::new(*a, port))).collect()
    }
}

/// `https://HOST:PORT/` for a socket address (IPv6 in brackets).
pub fn page_url(addr: SocketAddr) -> String {
    format!("https://{}/", addr)
}

/// `https://NAME:PORT/` for a host name.
pub fn page_url_named(name: &str, port: u16) -> String {
    format!("https://{name}:{port}/")
}

/// The interface addresses a socket bound to `bind` receives on, LAN ones only, in the order
/// a headset most likely reaches: private IPv4, other IPv4, then IPv6 (no link-local).
pub fn reachable(bind: IpAddr, ifaces: &[IpAddr]) -> Vec<IpAddr> {
    let usable = |a: &IpAddr| match a {
        IpAddr::V4(v) => !v.is_loopback() && !v.is_unspecified() && !v.is_link_local(),
        IpAddr::V6(v) => !v.is_loopback() && !v.is_unspecified() && !v.is_unicast_link_local(),
    };
    let mut out: Vec<IpAddr> = if bind.is_unspecified() {
        ifaces
            .iter()
            .copied()
            .filter(|a| usable(a) && (bind.is_ipv6() || a.is_ipv4()))
            .collect()
    } else if usable(&bind) {
        vec![bind]
    } else {
        vec![]
    };
    let rank = |a: &IpAddr| match a {
        IpAddr::V4(v) if v.is_private() => 0,
        IpAddr::V4(_) => 1,
        IpAddr::V6(_) => 2,
    };
    out.sort_by_key(rank); // stable: interface order within a rank
    out.dedup();
    out
}

/// A host name that can stand in a certificate and a URL: DNS labels of letters, digits and
/// hyphens (no leading or trailing hyphen), dot-separated, at most 253 bytes.
pub fn dns_name_ok(h: &str) -> bool {
    !h.is_empty()
        && h.len() <= 253
        && h.split('.').all(|l| {
            !l.is_empty()
                && l.len() <= 63
                && !l.starts_with('-')
                && !l.ends_with('-')
                && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
        })
        && h.parse::<IpAddr>().is_err()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ip(s: &str) -> IpAddr {
        s.parse().unwrap()
    }

    #[test]
    fn lan_addresses_are_ordered_and_loopback_and_link_local_left_out() {
        let ifaces = [ip("127.0.0.1"), ip("::1"), ip("203.0.113.7"), ip("192.168.1.20"), ip("fe80::1"), ip("2001:db8::5"), ip("169.254.3.3"), ip("10.0.0.2")];
        assert_eq!(reachable(ip("0.0.0.0"), &ifaces), vec![ip("192.168.1.20"), ip("10.0.0.2"), ip("203.0.113.7")]);
        assert_eq!(
            reachable(ip("::"), &ifaces),
            vec![ip("192.168.1.20"), ip("10.0.0.2"), ip("203.0.113.7"), ip("2001:db8::5")]
        );
        assert_eq!(reachable(ip("10.0.0.2"), &ifaces), vec![ip("10.0.0.2")]);
        assert!(reachable(ip("127.0.0.1"), &ifaces).is_empty());
    }

    #[test]
    fn names_hold_loopback_every_address_and_the_mdns_name() {
        let n = LocalNames { addrs: vec![ip("192.168.1.20"), ip("2001:db8::5")], hostname: Some("laptop".into()) };
        assert_eq!(
            n.cert_names(),
            ["localhost", "127.0.0.1", "::1", "192.168.1.20", "2001:db8::5", "laptop", "laptop.local"]
        );
        assert_eq!(n.urls(4434), ["https://192.168.1.20:4434/", "https://[2001:db8::5]:4434/"]);
        assert!(dns_name_ok("laptop") && dns_name_ok("my-pc.example.org"));
        assert!(!dns_name_ok("-x") && !dns_name_ok("a..b") && !dns_name_ok("a b") && !dns_name_ok("10.0.0.1") && !dns_name_ok(""));
    }
}
