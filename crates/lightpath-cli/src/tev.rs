//! Streaming images to the [tev](https://github.com/Tom94/tev) viewer over TCP, in its
//! IPC protocol (the same packets pbrt-v4 sends).
//!
//! Every packet is little-endian: a `u32` length of the whole packet (including the
//! length itself), a `u8` type, then the fields; strings are NUL-terminated, booleans
//! one byte.
//!
//! | type | packet       | fields                                                        |
//! |------|--------------|---------------------------------------------------------------|
//! | 2    | CloseImage   | name                                                          |
//! | 3    | UpdateImage  | grab focus, name, channel name, x, y, width, height (`i32`), width·height `f32` values, row-major |
//! | 4    | CreateImage  | grab focus, name, width, height, channel count (`i32`), channel names |
//!
//! An image is created once (channels `R`, `G`, `B`) and then updated a channel and a
//! tile of at most [`TILE`]² pixels per packet (64 KiB of values, well inside the 1 MiB
//! receive buffer tev starts with). tev being absent or going away is never an error:
//! the client warns once and stops sending.

use lightpath::film::Image;
use std::io::Write;
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

#[cfg(test)]
pub const CLOSE_IMAGE: u8 = 2;
pub const UPDATE_IMAGE: u8 = 3;
pub const CREATE_IMAGE: u8 = 4;

/// Tile edge of an update packet, in pixels (pbrt-v4 uses the same).
pub const TILE: u32 = 128;

const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// Builds one packet.
struct Packet(Vec<u8>);

impl Packet {
    fn new(kind: u8) -> Packet {
        let mut p = Packet(vec![0; 4]);
        p.0.push(kind);
        p
    }
    fn bool(mut self, b: bool) -> Self {
        self.0.push(b as u8);
        self
    }
    fn str(mut self, s: &str) -> Self {
        // A NUL inside would end the string early on tev's side.
        self.0.extend(s.bytes().filter(|&b| b != 0));
        self.0.push(0);
        self
    }
    fn i32(mut self, v: i32) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn f32s(mut self, values: impl Iterator<Item = f32>) -> Self {
        for v in values {
            self.0.extend_from_slice(&v.to_le_bytes());
        }
        self
    }
    fn finish(mut self) -> Vec<u8> {
        let n = self.0.len() as u32;
        self.0[..4].copy_from_slice(&n.to_le_bytes());
        self.0
    }
}

pub fn create_image(name: &str, width: u32, height: u32, grab_focus: bool) -> Vec<u8> {
    let mut p = Packet::new(CREATE_IMAGE)
        .bool(grab_focus)
        .str(name)
        .i32(width as i32)
        .i32(height as i32)
        .i32(CHANNELS.len() as i32);
    for c in CHANNELS {
        p = p.str(c);
    }
    p.finish()
}

/// One channel (0: R, 1: G, 2: B) of the tile at (`x`, `y`) of size `w`×`h`.
pub fn update_image(
    name: &str,
    image: &Image,
    channel: usize,
    x: u32,
    y: u32,
    w: u32,
    h: u32,
) -> Vec<u8> {
    let values = (y..y + h).flat_map(|py| (x..x + w).map(move |px| image.get(px, py)[channel]));
    Packet::new(UPDATE_IMAGE)
        .bool(false)
        .str(name)
        .str(CHANNELS[channel])
        .i32(x as i32)
        .i32(y as i32)
        .i32(w as i32)
        .i32(h as i32)
        .f32s(values)
        .finish()
}

/// Not sent by the renderer (the finished image stays open in tev); kept for the
/// protocol's completeness and the tests.
#[cfg(test)]
pub fn close_image(name: &str) -> Vec<u8> {
    Packet::new(CLOSE_IMAGE).str(name).finish()
}

/// A connection to tev that turns into a no-op after the first failure.
pub struct Tev {
    stream: Option<TcpStream>,
    address: String,
    name: String,
    created: bool,
}

impl Tev {
    /// Connects to `address` (`HOST:PORT`); failure is reported by the returned
    /// warning, and the client then does nothing.
    pub fn connect(address: &str, name: &str) -> (Tev, Option<String>) {
        let mut tev = Tev {
            stream: None,
            address: address.to_string(),
            name: name.to_string(),
            created: false,
        };
        let result = address
            .to_socket_addrs()
            .map_err(|e| e.to_string())
            .and_then(|addrs| {
                let mut last = "no address".to_string();
                for a in addrs {
                    match TcpStream::connect_timeout(&a, Duration::from_secs(2)) {
                        Ok(s) => return Ok(s),
                        Err(e) => last = e.to_string(),
                    }
                }
                Err(last)
            });
        match result {
            Ok(stream) => {
                let _ = stream.set_write_timeout(Some(Duration::from_secs(5)));
                let _ = stream.set_nodelay(true);
                tev.stream = Some(stream);
                (tev, None)
            }
            Err(e) => {
                let warning =
                    format!("cannot connect to tev at {address} ({e}); rendering without it");
                (tev, Some(warning))
            }
        }
    }

    pub fn connected(&self) -> bool {
        self.stream.is_some()
    }

    /// Sends the whole image; a failed send disconnects and returns a warning.
    pub fn send(&mut self, image: &Image) -> Option<String> {
        let stream = self.stream.as_mut()?;
        let mut result = Ok(());
        if !self.created {
            result = stream.write_all(&create_image(&self.name, image.width, image.height, true));
            self.created = result.is_ok();
        }
        'tiles: for y in (0..image.height).step_by(TILE as usize) {
            for x in (0..image.width).step_by(TILE as usize) {
                let (w, h) = (TILE.min(image.width - x), TILE.min(image.height - y));
                for c in 0..CHANNELS.len() {
                    if result.is_err() {
                        break 'tiles;
                    }
                    result = stream.write_all(&update_image(&self.name, image, c, x, y, w, h));
                }
            }
        }
        let result = result.and_then(|()| stream.flush());
        match result {
            Ok(()) => None,
            Err(e) => {
                self.stream = None;
                Some(format!(
                    "lost the connection to tev at {} ({e}); rendering without it",
                    self.address
                ))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packet_layout() {
        let p = create_image("a", 3, 2, true);
        let mut expected = vec![0u8; 4];
        expected.extend_from_slice(&[4, 1, b'a', 0]);
        expected.extend_from_slice(&3i32.to_le_bytes());
        expected.extend_from_slice(&2i32.to_le_bytes());
        expected.extend_from_slice(&3i32.to_le_bytes());
        expected.extend_from_slice(b"R\0G\0B\0");
        let n = expected.len() as u32;
        expected[..4].copy_from_slice(&n.to_le_bytes());
        assert_eq!(p, expected);

        let mut image = Image::new(3, 2);
        image.set(2, 1, glam_vec(1.0, 2.0, 3.0));
        let p = update_image("a", &image, 2, 1, 1, 2, 1);
        assert_eq!(p[4], 3);
        assert_eq!(&p[5..10], &[0, b'a', 0, b'B', 0]);
        let ints: Vec<i32> = p[10..26]
            .chunks(4)
            .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(ints, vec![1, 1, 2, 1]);
        assert_eq!(&p[26..30], &0f32.to_le_bytes());
        assert_eq!(&p[30..34], &3f32.to_le_bytes());
        assert_eq!(p.len(), 34);
        assert_eq!(u32::from_le_bytes(p[..4].try_into().unwrap()), 34);
        assert_eq!(close_image("xy"), vec![8, 0, 0, 0, 2, b'x', b'y', 0]);
    }

    fn glam_vec(x: f32, y: f32, z: f32) -> lightpath::math::Vec3 {
        lightpath::math::Vec3::new(x, y, z)
    }

    #[test]
    fn unreachable_viewer_is_a_warning() {
        // A port nobody listens on: bind one, learn its number, close it.
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let (mut tev, warning) = Tev::connect(&format!("127.0.0.1:{port}"), "x");
        assert!(warning.unwrap().contains("cannot connect to tev"));
        assert!(!tev.connected());
        assert!(tev.send(&Image::new(2, 2)).is_none());
        let (_, warning) = Tev::connect("not an address", "x");
        assert!(warning.is_some());
    }
}
