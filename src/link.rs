//! The protocol links, USART2 and USB CDC-ACM, each served by its own
//! [`firmware_app::Server`] (one link's framing state) on the one shared application: the
//! request handling is firmware-app's, tested on the host; this is only byte transport.

use crate::{with_app, SharedApp};
use embassy_futures::select::{select, Either};
use embassy_stm32::peripherals::USB_OTG_FS;
use embassy_stm32::usb::Driver;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_time::{with_timeout, Duration, Instant, Timer};
use embassy_usb::class::cdc_acm::CdcAcmClass;
use embedded_io_async::{Read, Write};
use firmware_app::{PersistItem, SaveQueue, Server, Step, TelemetryRoute};

/// The USB device driver.
pub type UsbDriver = Driver<'static, USB_OTG_FS>;
/// Full-speed bulk packets.
pub const USB_PACKET: usize = 64;
/// How long a USB packet may wait for the host to take it (a full-speed host polls
/// every millisecond when it reads).
const USB_WRITE: Duration = Duration::from_millis(50);

/// Saves asked for by the links' request handlers, one at a time (firmware-app's policy).
pub static SAVES: SaveQueue<CriticalSectionRawMutex> = SaveQueue::new();

/// Telemetry goes to the link that last received a valid frame (firmware-app's policy).
static TELEMETRY: TelemetryRoute = TelemetryRoute::new();

/// The USB CDC-ACM class as an `embedded-io-async` stream, so that both links are served
/// through the ecosystem's byte traits (firmware-app's `ByteStream` is the host's
/// non-blocking one; there is no third).
pub struct UsbPort(pub CdcAcmClass<'static, UsbDriver>);

impl embedded_io_async::ErrorType for UsbPort {
    type Error = core::convert::Infallible;
}

impl Read for UsbPort {
    /// Waits for a packet; 0 (not end of stream) after an unplug, once the host is back.
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        match self.0.read_packet(buf).await {
            Ok(n) => Ok(n),
            Err(_) => {
                // Unplugged or not configured yet.
                self.0.wait_connection().await;
                Ok(0)
            }
        }
    }
}

impl Write for UsbPort {
    /// Takes all of `buf`. A host that has the port configured but does not read it
    /// would block the link for ever: a packet not taken within `USB_WRITE` is dropped
    /// with the rest of the frame (the host's decoder resynchronises on the next
    /// delimiter), as on a line nobody listens to.
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        for packet in buf.chunks(USB_PACKET) {
            if !put(&mut self.0, packet).await {
                return Ok(buf.len());
            }
        }
        // A transfer that ends on a full packet needs a zero-length one to end it.
        if buf.len().is_multiple_of(USB_PACKET) {
            put(&mut self.0, &[]).await;
        }
        Ok(buf.len())
    }

    /// Every packet is handed to the USB stack as it is written.
    async fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// Sends `data`; what cannot be sent is lost, as on a line nobody listens to.
async fn send(link: &mut impl Write, data: &[u8]) {
    let _ = link.write_all(data).await;
}

/// One USB packet, or false if the host did not take it in time (or is gone).
async fn put(cdc: &mut CdcAcmClass<'static, UsbDriver>, packet: &[u8]) -> bool {
    matches!(
        with_timeout(USB_WRITE, cdc.write_packet(packet)).await,
        Ok(Ok(()))
    )
}

/// One received byte through the link's server, under the application's lock: the
/// length of an answer to send, or a save to make. Not inlined: both links share it.
#[inline(never)]
fn push(
    app: &SharedApp,
    server: &mut Server,
    byte: u8,
) -> Option<Result<usize, (u16, PersistItem)>> {
    let now = Instant::now().as_micros();
    with_app(app, |a| match server.push(byte, a, now) {
        Step::Idle => None,
        Step::Send(w) => Some(Ok(w.len())),
        Step::Persist { seq, item } => Some(Err((seq, item))),
    })
}

/// Serves one link for ever: requests through `server`, answers and (when this link
/// was the last to be spoken to) telemetry back, saves through the storage task.
pub async fn serve(app: &'static SharedApp, link: &mut (impl Read + Write), id: u8) -> ! {
    let mut server = Server::new();
    let mut buf = [0u8; USB_PACKET];
    loop {
        // Wake at least every 10 ms for telemetry.
        // Framing or overrun errors read as nothing: the decoder resynchronises on the
        // next delimiter.
        let n = match select(link.read(&mut buf), Timer::after_millis(10)).await {
            Either::First(n) => n.unwrap_or(0),
            Either::Second(()) => 0,
        };
        for &b in &buf[..n.min(buf.len())] {
            match push(app, &mut server, b) {
                None => {}
                Some(Ok(len)) => {
                    TELEMETRY.spoke(id);
                    send(link, server.last_frame(len)).await;
                }
                Some(Err((seq, item))) => {
                    TELEMETRY.spoke(id);
                    let ok = SAVES.save(item).await;
                    let r = with_app(app, |a| a.persisted(ok));
                    send(link, server.reply(seq, &r)).await;
                }
            }
        }
        if TELEMETRY.gets_telemetry(id) {
            let tele = with_app(app, |a| server.telemetry(a).map(|t| t.len()));
            if let Some(len) = tele {
                send(link, server.last_telemetry(len)).await;
            }
        }
    }
}
