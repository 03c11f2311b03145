//! The protocol USART (USART1, PA9 TX / PA10 RX, 115200 8N1): receive by interrupt into a ring
//! buffer, blocking transmit from the main loop.

use core::cell::RefCell;
use cortex_m::interrupt::Mutex;
use heapless::Deque;
use hvs_shared::runtime::protocol::BAUD_RATE;
use stm32f4xx_hal::{
    gpio::{PA10, PA9},
    interrupt, nb, pac,
    prelude::*,
    rcc::Rcc,
    serial::{self, RxListen, Serial},
};

/// Transmit half of the protocol USART.
pub type Tx = serial::Tx<pac::USART1>;
type Rx = serial::Rx<pac::USART1>;

/// Received bytes not yet taken by the main loop. Larger than a frame so a whole request
/// queues while a response is being sent. When it is full, bytes are dropped: the frame they
/// belonged to then fails to decode and is answered with `Error(Malformed)`.
const RING_LEN: usize = 256;

static RX: Mutex<RefCell<Option<Rx>>> = Mutex::new(RefCell::new(None));
static RING: Mutex<RefCell<Deque<u8, RING_LEN>>> = Mutex::new(RefCell::new(Deque::new()));

/// Configures USART1, starts receiving by interrupt, returns the transmit half.
pub fn init(usart: pac::USART1, tx_pin: PA9, rx_pin: PA10, rcc: &mut Rcc) -> Tx {
    let serial: Serial<pac::USART1> =
        match Serial::new(usart, (tx_pin, rx_pin), BAUD_RATE.bps(), rcc) {
            Ok(s) => s,
            Err(_) => crate::halt(crate::HaltReason::LinkInit),
        };
    let (tx, mut rx) = serial.split();
    rx.listen();
    cortex_m::interrupt::free(|cs| RX.borrow(cs).replace(Some(rx)));
    // SAFETY: the handler below only touches RX and RING through critical sections.
    unsafe { pac::NVIC::unmask(pac::Interrupt::USART1) };
    tx
}

/// The next received byte, if any.
pub fn pop() -> Option<u8> {
    cortex_m::interrupt::free(|cs| RING.borrow(cs).borrow_mut().pop_front())
}

/// Sends all of `bytes`, blocking.
pub fn write_all(tx: &mut Tx, bytes: &[u8]) {
    // The only error is a USART fault; a response is then lost and the host retries.
    let _ = embedded_io::Write::write_all(tx, bytes);
}

#[interrupt]
fn USART1() {
    cortex_m::interrupt::free(|cs| {
        let mut rx = RX.borrow(cs).borrow_mut();
        let Some(rx) = rx.as_mut() else { return };
        let mut ring = RING.borrow(cs).borrow_mut();
        loop {
            match rx.read() {
                Ok(b) => {
                    // Full ring: drop the byte (see RING_LEN).
                    let _ = ring.push_back(b);
                }
                // Overrun, framing or noise: the byte is lost, the flag is cleared by the read.
                Err(nb::Error::Other(_)) => continue,
                Err(nb::Error::WouldBlock) => break,
            }
        }
    });
}
