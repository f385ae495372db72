//! The link's settings (a TOML file, `harvest remote --link FILE`, and the station's
//! `--link FILE`) and the security rules they must pass before a Zenoh session opens:
//!
//! - With no file the robot listens on loopback only (`tcp/127.0.0.1:7447`) and the station
//!   connects there: nothing reaches the network unless configured.
//! - Only `tcp/` and `tls/` endpoints (the only transports built). An endpoint whose host is
//!   not loopback must be `tls/`, with a CA to check the peer, and with user/password
//!   authentication or mutual TLS (client certificates).
//! - Multicast and gossip scouting are always off: a station connects to robots by address.
//! - When users are configured (a listener's `dictionary_file`), access control is on with
//!   default deny: `operators` may query the command keys, `viewers` (and any other known user)
//!   may only watch; an unknown or unauthenticated peer gets nothing.
//!
//! [`LinkSettings::zenoh_config`] turns checked settings into Zenoh's JSON configuration; the
//! process hands it to Zenoh unchanged.

use std::net::IpAddr;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde_json::{Value, json};
use thiserror::Error;

/// The robot's listener and the station's connection when nothing is configured.
pub const DEFAULT_LOOPBACK_ENDPOINT: &str = "tcp/127.0.0.1:7447";

/// The link's settings file.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkSettings {
    /// Endpoints this side listens on (`tcp/127.0.0.1:7447`, `tls/10.0.0.5:7447`).
    #[serde(default)]
    pub listen: Vec<String>,
    /// Endpoints this side connects to (a station: each robot's).
    #[serde(default)]
    pub connect: Vec<String>,
    #[serde(default)]
    pub tls: Option<TlsSettings>,
    #[serde(default)]
    pub auth: Option<AuthSettings>,
    #[serde(default)]
    pub access: Option<AccessSettings>,
}

/// TLS files (PEM paths).
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TlsSettings {
    /// CA that signed the peer's certificate.
    pub root_ca_certificate: PathBuf,
    /// This side's certificate and key when it listens.
    #[serde(default)]
    pub listen_certificate: Option<PathBuf>,
    #[serde(default)]
    pub listen_private_key: Option<PathBuf>,
    /// This side's certificate and key when it connects (mutual TLS).
    #[serde(default)]
    pub connect_certificate: Option<PathBuf>,
    #[serde(default)]
    pub connect_private_key: Option<PathBuf>,
    /// A listener requires client certificates.
    #[serde(default)]
    pub mutual: bool,
}

/// User/password authentication.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AuthSettings {
    /// The listener's users: a file of `user:password` lines (mode 0600).
    #[serde(default)]
    pub dictionary_file: Option<PathBuf>,
    /// The name this side presents when it connects.
    #[serde(default)]
    pub user: Option<String>,
    /// A file holding the password this side presents (mode 0600; one line).
    #[serde(default)]
    pub password_file: Option<PathBuf>,
}

/// Who may command.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccessSettings {
    /// Users that may send operator commands (they still need the control token).
    #[serde(default)]
    pub operators: Vec<String>,
    /// Users that may only watch.
    #[serde(default)]
    pub viewers: Vec<String>,
}

/// Settings that would open the robot beyond what is allowed, or cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SettingsError {
    #[error("endpoint `{0}`: expected `tcp/<host>:<port>` or `tls/<host>:<port>`")]
    BadEndpoint(String),
    #[error(
        "endpoint `{0}` is not loopback: it must be `tls/` (with [tls] root_ca_certificate) and authenticated ([auth] user/password or [tls] mutual certificates)"
    )]
    UnprotectedEndpoint(String),
    #[error("endpoint `{endpoint}` is TLS: [tls] needs {missing}")]
    MissingTls {
        endpoint: String,
        missing: &'static str,
    },
    #[error("[auth]: {0}")]
    Auth(String),
    #[error("[access]: {0}")]
    Access(String),
    #[error("{path}: {message}")]
    File { path: PathBuf, message: String },
}

/// Whether an endpoint is a listener or a connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Direction {
    Listen,
    Connect,
}

/// `(protocol, host)` of `tcp/host:port` or `tls/host:port` (a `#...` tail of Zenoh options is
/// refused: the settings say everything).
fn split_endpoint(endpoint: &str) -> Option<(&str, &str)> {
    let (protocol, address) = endpoint.split_once('/')?;
    if !matches!(protocol, "tcp" | "tls") || address.contains(['#', '?', '/']) {
        return None;
    }
    let (host, port) = address.rsplit_once(':')?;
    port.parse::<u16>().ok()?;
    let host = host.trim_start_matches('[').trim_end_matches(']');
    (!host.is_empty()).then_some((protocol, host))
}

/// Whether `host` can only be this machine.
pub fn is_loopback_host(host: &str) -> bool {
    host == "localhost" || host.parse::<IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

impl LinkSettings {
    /// The robot's settings when no file is given: loopback only.
    pub fn robot_default() -> Self {
        Self {
            listen: vec![DEFAULT_LOOPBACK_ENDPOINT.to_owned()],
            ..Self::default()
        }
    }

    /// The station's settings when no file is given: the robot on this machine's loopback.
    pub fn station_default() -> Self {
        Self {
            connect: vec![DEFAULT_LOOPBACK_ENDPOINT.to_owned()],
            ..Self::default()
        }
    }

    fn has_password_auth(&self, direction: Direction) -> bool {
        self.auth.as_ref().is_some_and(|auth| match direction {
            Direction::Listen => auth.dictionary_file.is_some(),
            Direction::Connect => auth.user.is_some() && auth.password_file.is_some(),
        })
    }

    fn has_mutual_tls(&self, direction: Direction) -> bool {
        self.tls.as_ref().is_some_and(|tls| match direction {
            Direction::Listen => tls.mutual,
            Direction::Connect => {
                tls.connect_certificate.is_some() && tls.connect_private_key.is_some()
            }
        })
    }

    fn check_endpoint(&self, endpoint: &str, direction: Direction) -> Result<(), SettingsError> {
        let (protocol, host) = split_endpoint(endpoint)
            .ok_or_else(|| SettingsError::BadEndpoint(endpoint.to_owned()))?;
        if protocol == "tls" {
            let tls = self.tls.as_ref().ok_or(SettingsError::MissingTls {
                endpoint: endpoint.to_owned(),
                missing: "root_ca_certificate",
            })?;
            if direction == Direction::Listen
                && (tls.listen_certificate.is_none() || tls.listen_private_key.is_none())
            {
                return Err(SettingsError::MissingTls {
                    endpoint: endpoint.to_owned(),
                    missing: "listen_certificate and listen_private_key",
                });
            }
        }
        if is_loopback_host(host) {
            return Ok(());
        }
        let authenticated = self.has_password_auth(direction) || self.has_mutual_tls(direction);
        if protocol != "tls" || !authenticated {
            return Err(SettingsError::UnprotectedEndpoint(endpoint.to_owned()));
        }
        Ok(())
    }

    /// Checks the rules of the module docs.
    pub fn check(&self) -> Result<(), SettingsError> {
        for endpoint in &self.listen {
            self.check_endpoint(endpoint, Direction::Listen)?;
        }
        for endpoint in &self.connect {
            self.check_endpoint(endpoint, Direction::Connect)?;
        }
        if let Some(auth) = &self.auth
            && auth.user.is_some() != auth.password_file.is_some()
        {
            return Err(SettingsError::Auth(
                "`user` and `password_file` go together".to_owned(),
            ));
        }
        let users = self.auth.as_ref().and_then(|a| a.dictionary_file.as_ref());
        match (&self.access, users) {
            (Some(access), None) if !access.operators.is_empty() || !access.viewers.is_empty() => {
                return Err(SettingsError::Access(
                    "operators and viewers need [auth] dictionary_file (who is who)".to_owned(),
                ));
            }
            (Some(access), Some(_)) => {
                if let Some(both) = access.operators.iter().find(|u| access.viewers.contains(u)) {
                    return Err(SettingsError::Access(format!(
                        "`{both}` is both an operator and a viewer"
                    )));
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// The password this side presents, read from its file (which must not be readable by
    /// others).
    pub fn read_password(&self) -> Result<Option<String>, SettingsError> {
        let Some(path) = self.auth.as_ref().and_then(|a| a.password_file.as_ref()) else {
            return Ok(None);
        };
        check_private(path)?;
        let text = std::fs::read_to_string(path).map_err(|e| SettingsError::File {
            path: path.clone(),
            message: e.to_string(),
        })?;
        Ok(Some(text.trim_end_matches(['\n', '\r']).to_owned()))
    }

    /// Zenoh's configuration (JSON) for these checked settings; `password` from
    /// [`Self::read_password`]; `key_root` is what the access rules cover (`harvest/v1/<robot>`
    /// on a robot).
    pub fn zenoh_config(
        &self,
        password: Option<&str>,
        key_root: &str,
    ) -> Result<Value, SettingsError> {
        self.check()?;
        if let Some(path) = self.auth.as_ref().and_then(|a| a.dictionary_file.as_ref()) {
            check_private(path)?;
        }
        let mut config = json!({
            "mode": "peer",
            "listen": { "endpoints": self.listen },
            "connect": {
                "endpoints": self.connect,
                // Keep trying in the background: a robot out of reach is not an error, and a
                // link that comes back is used again.
                "timeout_ms": -1,
                "exit_on_failure": false,
                "retry": {
                    "period_init_ms": 250,
                    "period_max_ms": 1000,
                    "period_increase_factor": 2.0,
                },
            },
            "scouting": {
                "multicast": { "enabled": false },
                "gossip": { "enabled": false },
            },
        });
        let mut transport = serde_json::Map::new();
        if let Some(tls) = &self.tls {
            let path = |p: &Option<PathBuf>| p.as_ref().map(|p| p.display().to_string());
            transport.insert(
                "link".to_owned(),
                json!({ "tls": {
                    "root_ca_certificate": tls.root_ca_certificate.display().to_string(),
                    "listen_certificate": path(&tls.listen_certificate),
                    "listen_private_key": path(&tls.listen_private_key),
                    "connect_certificate": path(&tls.connect_certificate),
                    "connect_private_key": path(&tls.connect_private_key),
                    "enable_mtls": tls.mutual,
                    "verify_name_on_connect": true,
                }}),
            );
        }
        if let Some(auth) = &self.auth {
            transport.insert(
                "auth".to_owned(),
                json!({ "usrpwd": {
                    "user": auth.user,
                    "password": password,
                    "dictionary_file": auth.dictionary_file.as_ref().map(|p| p.display().to_string()),
                }}),
            );
        }
        if !transport.is_empty() {
            config["transport"] = Value::Object(transport);
        }
        if self
            .auth
            .as_ref()
            .is_some_and(|a| a.dictionary_file.is_some())
        {
            let access = self.access.clone().unwrap_or_default();
            config["access_control"] = access_control(&access, key_root);
        }
        Ok(config)
    }
}

/// Default deny; everyone known may watch `key_root/**`; operators may also query the command
/// and e-stop keys.
fn access_control(access: &AccessSettings, key_root: &str) -> Value {
    let watchers: Vec<&String> = access.operators.iter().chain(&access.viewers).collect();
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    if !watchers.is_empty() {
        subjects.push(json!({ "id": "watchers", "usernames": watchers }));
        policies.push(json!({ "rules": ["watch-out", "watch-in"], "subjects": ["watchers"] }));
    }
    if !access.operators.is_empty() {
        subjects.push(json!({ "id": "operators", "usernames": access.operators }));
        policies.push(json!({ "rules": ["command-in", "command-out"], "subjects": ["operators"] }));
    }
    let commands = [
        format!("{key_root}/{}", crate::keys::COMMAND),
        format!("{key_root}/{}", crate::keys::ESTOP),
    ];
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": [
            {
                "id": "watch-out",
                "messages": ["put", "delete", "liveliness_token", "reply"],
                "flows": ["egress"],
                "permission": "allow",
                "key_exprs": [format!("{key_root}/**")],
            },
            {
                // A fleet station subscribes to every robot at once (`harvest/v1/*/...`).
                "id": "watch-in",
                "messages": ["declare_subscriber", "declare_liveliness_subscriber", "liveliness_query"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": [format!("{}/**", crate::keys::ROOT)],
            },
            {
                "id": "command-in",
                "messages": ["query"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": commands,
            },
            {
                // Operators must also learn that the command queryables exist: without their
                // declaration a station never sends the query.
                "id": "command-out",
                "messages": ["reply", "declare_queryable"],
                "flows": ["egress"],
                "permission": "allow",
                "key_exprs": commands,
            },
        ],
        "subjects": subjects,
        "policies": policies,
    })
}

/// A secret file must not be readable by group or others.
fn check_private(path: &Path) -> Result<(), SettingsError> {
    use std::os::unix::fs::PermissionsExt;
    let meta = std::fs::metadata(path).map_err(|e| SettingsError::File {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    let mode = meta.permissions().mode() & 0o777;
    if mode & 0o077 != 0 {
        return Err(SettingsError::File {
            path: path.to_owned(),
            message: format!("readable by others (mode {mode:o}); expected 600"),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> LinkSettings {
        toml::from_str(text).expect("settings")
    }

    #[test]
    fn the_defaults_stay_on_loopback() {
        let robot = LinkSettings::robot_default();
        robot.check().expect("loopback is allowed");
        let config = robot.zenoh_config(None, "harvest/v1/r1").expect("config");
        assert_eq!(config["listen"]["endpoints"], json!(["tcp/127.0.0.1:7447"]));
        assert_eq!(config["scouting"]["multicast"]["enabled"], json!(false));
        assert_eq!(config["scouting"]["gossip"]["enabled"], json!(false));
        assert!(config.get("access_control").is_none());
        LinkSettings::station_default().check().expect("station");
    }

    #[test]
    fn beyond_loopback_needs_tls_and_authentication() {
        for endpoint in ["tcp/0.0.0.0:7447", "tcp/10.0.0.5:7447", "tcp/[::]:7447"] {
            let s = LinkSettings {
                listen: vec![endpoint.to_owned()],
                ..LinkSettings::default()
            };
            assert_eq!(
                s.check(),
                Err(SettingsError::UnprotectedEndpoint(endpoint.to_owned()))
            );
        }
        let tls_only = parse(
            r#"listen = ["tls/10.0.0.5:7447"]
               [tls]
               root_ca_certificate = "ca.pem"
               listen_certificate = "robot.pem"
               listen_private_key = "robot.key""#,
        );
        assert!(matches!(
            tls_only.check(),
            Err(SettingsError::UnprotectedEndpoint(_))
        ));
        let with_users = parse(
            r#"listen = ["tls/10.0.0.5:7447"]
               [tls]
               root_ca_certificate = "ca.pem"
               listen_certificate = "robot.pem"
               listen_private_key = "robot.key"
               [auth]
               dictionary_file = "users.txt"
               [access]
               operators = ["op"]
               viewers = ["view"]"#,
        );
        with_users.check().expect("tls + users");
        let with_certs = parse(
            r#"connect = ["tls/10.0.0.5:7447"]
               [tls]
               root_ca_certificate = "ca.pem"
               connect_certificate = "station.pem"
               connect_private_key = "station.key""#,
        );
        with_certs.check().expect("tls + client certificate");
        let no_key = parse(
            r#"listen = ["tls/127.0.0.1:7447"]
               [tls]
               root_ca_certificate = "ca.pem""#,
        );
        assert!(matches!(
            no_key.check(),
            Err(SettingsError::MissingTls { .. })
        ));
        for bad in [
            "udp/127.0.0.1:7447",
            "tcp/127.0.0.1",
            "tcp/127.0.0.1:7447#iface=lo",
            "quic/1.2.3.4:1",
        ] {
            let s = LinkSettings {
                connect: vec![bad.to_owned()],
                ..LinkSettings::default()
            };
            assert_eq!(
                s.check(),
                Err(SettingsError::BadEndpoint(bad.to_owned())),
                "{bad}"
            );
        }
    }

    #[test]
    fn viewers_cannot_query_the_command_keys() {
        let access = AccessSettings {
            operators: vec!["op".to_owned()],
            viewers: vec!["view".to_owned()],
        };
        let acl = access_control(&access, "harvest/v1/r1");
        assert_eq!(acl["default_permission"], json!("deny"));
        let policies = acl["policies"].as_array().expect("policies");
        let command_policy = policies
            .iter()
            .find(|p| {
                p["rules"]
                    .as_array()
                    .is_some_and(|r| r.contains(&json!("command-in")))
            })
            .expect("command policy");
        assert_eq!(command_policy["subjects"], json!(["operators"]));
        let operators = acl["subjects"]
            .as_array()
            .expect("subjects")
            .iter()
            .find(|s| s["id"] == json!("operators"))
            .expect("operators");
        assert_eq!(operators["usernames"], json!(["op"]));
        let both = parse(
            r#"[auth]
               dictionary_file = "u"
               [access]
               operators = ["a"]
               viewers = ["a"]"#,
        );
        assert!(matches!(both.check(), Err(SettingsError::Access(_))));
        let unknown = toml::from_str::<LinkSettings>("listen = []\nscouting = true");
        assert!(unknown.is_err());
    }
}
