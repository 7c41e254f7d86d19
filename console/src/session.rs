//! The session of one `wheelcal` process (or one `wheelcal console` prompt): the port
//! given on the command line and the connection opened on it the first time a command
//! needs it. Kept apart from the dispatcher so the command modules can borrow it.

use crate::client::Client;
use crate::link;
use anyhow::{Context, Result};

/// The connection a session holds: the serial port, locked against other wheelcals
/// and relaying their E-stops.
pub type PortClient = Client<crate::stop::LockedPort>;

/// A lazily opened connection.
pub struct Ctx {
    /// The serial port given with --port or WHEELCAL_PORT.
    pub port: Option<String>,
    /// Baud rate of the serial port.
    pub baud: u32,
    /// The open connection, once a command has needed one.
    pub client: Option<PortClient>,
    /// Relays E-stops from other terminals to the port while this process holds it.
    pub relay: Option<crate::stop::Relay>,
}

impl Ctx {
    /// The connection, opened (and greeted) on first use, so commands that never talk to
    /// a board need no --port.
    pub(crate) fn client(&mut self) -> Result<&mut PortClient> {
        if self.client.is_none() {
            let port = self
                .port
                .clone()
                .context("this command talks to a board: give --port DEV (or set WHEELCAL_PORT)")?;
            let link = link::open_serial(&port, self.baud)?;
            let (link, relay) = crate::stop::hold(&port, link);
            let mut c = Client::new(link, &port);
            c.hello()?;
            self.client = Some(c);
            self.relay = relay;
        }
        Ok(self.client.as_mut().expect("just connected"))
    }
}

/// An I/O failure on the open port (a broken pipe: the board or its cable went away)
/// names the port, so a person with several boards knows which one.
pub(crate) fn name_the_port(e: anyhow::Error, ctx: &Ctx) -> anyhow::Error {
    let (Some(_), Some(port)) = (&ctx.client, &ctx.port) else {
        return e;
    };
    let io = e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>().is_some()
            || c.downcast_ref::<crate::client::ClientError>()
                .is_some_and(|ce| matches!(ce, crate::client::ClientError::Io(_)))
    });
    if io && !format!("{e:#}").contains(port.as_str()) {
        e.context(format!("port {port}"))
    } else {
        e
    }
}
