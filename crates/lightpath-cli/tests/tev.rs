//! `render --tev HOST:PORT`: a stand-in for the tev viewer on loopback speaks the
//! receiving side of tev's IPC protocol, and the updates it receives must assemble into
//! exactly the image `render` writes.

use std::io::Read;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// A packet as tev's reader sees it.
#[derive(Debug)]
enum Packet {
    Create {
        name: String,
        width: i32,
        height: i32,
        channels: Vec<String>,
    },
    Update {
        name: String,
        channel: String,
        x: i32,
        y: i32,
        width: i32,
        height: i32,
        values: Vec<f32>,
    },
    /// Parsed for completeness; the renderer leaves its image open.
    #[allow(dead_code)]
    Close { name: String },
}

/// Reads the fields of one packet body (after length and type).
struct Fields<'a>(&'a [u8]);

impl Fields<'_> {
    fn take(&mut self, n: usize) -> &[u8] {
        assert!(self.0.len() >= n, "packet too short");
        let (a, b) = self.0.split_at(n);
        self.0 = b;
        a
    }
    fn bool(&mut self) -> bool {
        let b = self.take(1)[0];
        assert!(b <= 1, "bool byte {b}");
        b == 1
    }
    fn i32(&mut self) -> i32 {
        i32::from_le_bytes(self.take(4).try_into().unwrap())
    }
    fn string(&mut self) -> String {
        let end = self.0.iter().position(|&b| b == 0).expect("NUL-terminated");
        let s = String::from_utf8(self.0[..end].to_vec()).unwrap();
        self.0 = &self.0[end + 1..];
        s
    }
}

/// Splits a byte stream into packets: `u32` length (including itself), `u8` type, body.
fn parse(stream: &[u8]) -> Vec<Packet> {
    let mut packets = Vec::new();
    let mut rest = stream;
    while !rest.is_empty() {
        assert!(rest.len() >= 5, "truncated packet header");
        let len = u32::from_le_bytes(rest[..4].try_into().unwrap()) as usize;
        assert!(len >= 5 && len <= rest.len(), "bad packet length {len}");
        // tev's receive buffer starts at 1 MiB.
        assert!(len <= 1 << 20, "packet of {len} bytes");
        let kind = rest[4];
        let mut f = Fields(&rest[5..len]);
        let packet = match kind {
            4 => {
                let _grab_focus = f.bool();
                let name = f.string();
                let (width, height) = (f.i32(), f.i32());
                let n = f.i32();
                let channels = (0..n).map(|_| f.string()).collect();
                Packet::Create {
                    name,
                    width,
                    height,
                    channels,
                }
            }
            3 => {
                let _grab_focus = f.bool();
                let name = f.string();
                let channel = f.string();
                let (x, y, width, height) = (f.i32(), f.i32(), f.i32(), f.i32());
                let data = f.take((width * height * 4) as usize);
                let values = data
                    .chunks(4)
                    .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                    .collect();
                Packet::Update {
                    name,
                    channel,
                    x,
                    y,
                    width,
                    height,
                    values,
                }
            }
            2 => Packet::Close { name: f.string() },
            other => panic!("unexpected packet type {other}"),
        };
        assert!(
            f.0.is_empty(),
            "{} bytes left in a type-{kind} packet",
            f.0.len()
        );
        packets.push(packet);
        rest = &rest[len..];
    }
    packets
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("lightpath-tev-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const SCENE: &str = r#"<integrator type="ao" distance="2">
    <scene>
        <camera type="perspective">
            <integer name="width" value="150"/>
            <integer name="height" value="70"/>
            <transform><lookat origin="0,-1,-5" target="0,0,0" up="0,-1,0"/></transform>
        </camera>
        <instance><shape type="sphere"/></instance>
        <instance>
            <shape type="plane"/>
            <transform><rotate axis="1,0,0" angle="-90"/><translate y="1"/></transform>
        </instance>
    </scene>
    <sampler type="independent" count="8"/>
</integrator>
"#;

fn render(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lightpath"))
        .args(["render", "s.xml", "-o", "out.exr"])
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

#[test]
fn tev_updates_assemble_into_the_final_image() {
    let dir = temp_dir("stream");
    std::fs::write(dir.join("s.xml"), SCENE).unwrap();
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let server = std::thread::spawn(move || {
        let (mut socket, _) = listener.accept().unwrap();
        socket
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        let mut bytes = Vec::new();
        socket.read_to_end(&mut bytes).unwrap();
        bytes
    });
    let out = render(&dir, &["--tev", &format!("127.0.0.1:{port}")]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning"));
    let packets = parse(&server.join().unwrap());

    // First the image is created, then only updated.
    let Some(Packet::Create {
        name,
        width,
        height,
        channels,
    }) = packets.first()
    else {
        panic!("first packet: {:?}", packets.first());
    };
    assert_eq!((*width, *height), (150, 70));
    assert_eq!(channels, &["R", "G", "B"]);
    let (w, h) = (*width as usize, *height as usize);
    let mut assembled = vec![[f32::NAN; 3]; w * h];
    let mut rounds = 0;
    for p in &packets[1..] {
        let Packet::Update {
            name: n,
            channel,
            x,
            y,
            width,
            height,
            values,
        } = p
        else {
            panic!("unexpected {p:?}");
        };
        assert_eq!(n, name);
        let c = ["R", "G", "B"].iter().position(|k| k == channel).unwrap();
        if (*x, *y, c) == (0, 0, 0) {
            rounds += 1;
        }
        assert!(*x >= 0 && *y >= 0 && x + width <= w as i32 && y + height <= h as i32);
        assert!(*width <= 128 && *height <= 128, "tile {width}x{height}");
        for ty in 0..*height as usize {
            for tx in 0..*width as usize {
                assembled[(*y as usize + ty) * w + *x as usize + tx][c] =
                    values[ty * *width as usize + tx];
            }
        }
    }
    // One update of the whole image per pass: 1, 2, 4, 8 spp.
    assert_eq!(rounds, 4, "updates per pass");
    let image = lightpath::io::image::read_image(&dir.join("out.exr"), None).unwrap();
    assert_eq!((image.width as usize, image.height as usize), (w, h));
    for (i, (a, p)) in assembled.iter().zip(&image.pixels).enumerate() {
        assert_eq!(
            a.map(f32::to_bits),
            p.to_array().map(f32::to_bits),
            "pixel ({}, {})",
            i % w,
            i / w
        );
    }
}

/// No viewer listening: a warning, and the image is still rendered.
#[test]
fn missing_viewer_is_a_warning() {
    let dir = temp_dir("missing");
    std::fs::write(dir.join("s.xml"), SCENE).unwrap();
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let out = render(&dir, &["--tev", &format!("127.0.0.1:{port}")]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: cannot connect to tev"),
        "{stderr}"
    );
    assert!(dir.join("out.exr").exists());
}

/// A viewer that goes away mid-render: a warning, and the image is still rendered.
#[test]
fn viewer_going_away_is_a_warning() {
    let dir = temp_dir("away");
    std::fs::write(
        dir.join("s.xml"),
        SCENE.replace("count=\"8\"", "count=\"64\""),
    )
    .unwrap();
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let server = std::thread::spawn(move || {
        // Accept, read the first few bytes, hang up.
        let (mut socket, _) = listener.accept().unwrap();
        let mut first = [0u8; 16];
        socket.read_exact(&mut first).unwrap();
        drop(socket);
        first
    });
    let out = render(
        &dir,
        &["--tev", &format!("127.0.0.1:{port}"), "--spp", "64"],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(dir.join("out.exr").exists());
    assert_eq!(server.join().unwrap()[4], 4, "CreateImage first");
    // The send that notices the closed socket warns (it may also go unnoticed if every
    // byte fit in the socket buffers before the hang-up; then there is nothing to say).
    let warnings = stderr.matches("lost the connection to tev").count();
    assert!(warnings <= 1, "{stderr}");
}
