//! Real paintings for styles in tests, benchmarks and the CLI (`--style painting:KEY`):
//! public-domain works from Debian's `gcompris-qt-data` (the `paintings` puzzle; the
//! WebMuseum's scans, packaged under GPL-3.0-or-later).
//!
//! The package ships each painting cut into jigsaw pieces (binary alpha, tabs and blanks)
//! plus a board file that places each piece by its centre on a 702×515 board.
//! `scripts/setup-styles.sh` extracts the pieces (SHA-256 checked there as here); `path`
//! puts them back together into the whole painting, once, as `KEY.png` in the style
//! directory. A single piece is not a usable style: a quarter of a piece's rectangle is
//! transparent, which a style loader has to fill with something the painter never painted
//! (white, here), and a piece holds a sixth of the composition.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use sha2::{Digest, Sha256};

/// The command that fetches the paintings.
pub const SETUP_COMMAND: &str = "bash scripts/setup-styles.sh";

/// The prefix of a `--style` argument that names a painting here instead of a file.
pub const STYLE_PREFIX: &str = "painting:";

/// The puzzle board every piece position is a fraction of (`board*_0.qml`).
const BOARD: (f64, f64) = (702.0, 515.0);

/// One jigsaw piece: its file in the package and its centre as a fraction of the board.
#[derive(Clone, Copy, Debug)]
pub struct Piece {
    pub file: &'static str,
    pub sha256: &'static str,
    pub x: f64,
    pub y: f64,
}

#[derive(Clone, Copy, Debug)]
pub struct Painting {
    /// Short name used by tests, benchmarks and `--style painting:KEY`.
    pub key: &'static str,
    pub title: &'static str,
    pub pieces: &'static [Piece],
}

const fn piece(file: &'static str, sha256: &'static str, x: f64, y: f64) -> Piece {
    Piece { file, sha256, x, y }
}

/// The same files and hashes as `scripts/setup-styles.sh`; positions from the package's
/// `board22_0.qml`, `board1_0.qml`, `board19_0.qml`, `board7_0.qml`, `board21_0.qml` and
/// `board20_0.qml`. The first three are the paintings the stylization defaults were
/// measured on; the last three were added later as held-out styles (BENCH.md §5j).
pub const PAINTINGS: [Painting; 6] = [
    Painting {
        key: "vangogh",
        title: "Vincent van Gogh, Village Street in Auvers (1890)",
        pieces: &[
            piece("gogh_auvert_1.webp", "81f84ce20f31486197f459635ddeef042344c694af6fa130418a36b1d45a6904", 0.204, 0.224),
            piece("gogh_auvert_2.webp", "c4518c2389a6c572ad1ea623479e7a5030f3aa59dedc9c4cac73d55cda96c86c", 0.489, 0.224),
            piece("gogh_auvert_3.webp", "1aefb708e7c36a0e4c7c718e8cd2fd37d8321d7a4018d916f149314e4d4bfb98", 0.774, 0.224),
            piece("gogh_auvert_4.webp", "8cdc157e260d5d1864198c72951275c405b6f74568c836f285781caba0895f3c", 0.204, 0.681),
            piece("gogh_auvert_5.webp", "4bcb1e64c44022b79a56aba86643fdca26bad5d2a908c56400240fe9f08f1142", 0.489, 0.681),
            piece("gogh_auvert_6.webp", "b8ab1e32b422995ced0bce842a126da84a9db9d3eaba003934eee3c7ed915204", 0.774, 0.681),
        ],
    },
    Painting {
        key: "renoir",
        title: "Pierre-Auguste Renoir, Bal du moulin de la Galette (1876)",
        pieces: &[
            piece("renoir-moulin_de_la_galette-1.webp", "78880d194c3be92da64d89bca581e09c699303f7848c84f653f6cca0a14e2422", 0.255, 0.283),
            piece("renoir-moulin_de_la_galette-2.webp", "297bdebac908b464b7b76a3555cbfa2192816bc660859dadc6041caae5f55617", 0.533, 0.283),
            piece("renoir-moulin_de_la_galette-3.webp", "185c721373176d28f518a5625894def2389bd29b0be65ddef802a48e34898c57", 0.782, 0.327),
            piece("renoir-moulin_de_la_galette-4.webp", "182d1f65643f33d6583b9a3b3a6831af42dc0f0e11c65414e5656e13e619dbf7", 0.226, 0.651),
            piece("renoir-moulin_de_la_galette-5.webp", "593aaecdb2bc1cfbd6524348538abdd82242f4d70aaeb20a3b932d494e2d9c1f", 0.504, 0.651),
            piece("renoir-moulin_de_la_galette-6.webp", "e9358ce944f2f77fc618d6c3d357e3e3aec4dc7626bff40be1b994ad2bf640a0", 0.781, 0.69),
        ],
    },
    Painting {
        key: "kandinsky",
        title: "Wassily Kandinsky, Composition VIII (1923)",
        pieces: &[
            piece("kandinky_1.webp", "67bcd29206ed353a21f6ea5526d1b4f77f4647f6d7e1d8f3f4bef6c2298b65c5", 0.167, 0.283),
            piece("kandinky_2.webp", "0315468377f7f36584bb0e46e1e201a525aa7c1bc9d1685af7990248c68a7255", 0.405, 0.283),
            piece("kandinky_3.webp", "f9518aa6512a0e454a22e850f77d43ed7509e8a098fb5dad5ad22c10fd32e51b", 0.642, 0.228),
            piece("kandinky_4.webp", "92e3ebbaa42df5af6129dcb749a0f6cfa9749a469410077b6d8d00ac2b886db9", 0.85, 0.228),
            piece("kandinky_5.webp", "9fab6cfbfb69cb6f4089ba1bf81cf40e32b4b61125ca1ef9ae50c1461362377f", 0.138, 0.673),
            piece("kandinky_6.webp", "4d96b7997185047abc6ca0c77d9c742c9b9aea6514e14e5cb7865d4b723aff54", 0.376, 0.673),
            piece("kandinky_7.webp", "b7567aacb05ec786f11d4a0da407b95d4a1b38675b2462646cd515e865cce500", 0.642, 0.618),
            piece("kandinky_8.webp", "0c7b9d5d01972843c9a4049007bb8b22c8ab352f656782d5fd7dd4dfb9cea297", 0.85, 0.618),
        ],
    },
    Painting {
        key: "greatwave",
        title: "Katsushika Hokusai, The Great Wave off Kanagawa (1823–1829)",
        pieces: &[
            piece("GreatWave_a1.webp", "0e83968ebf461cba0bc90021e78ac3934ed41181a1c2f3d587350c41f5bdc7e1", 0.147, 0.242),
            piece("GreatWave_a2.webp", "35110e1c3ed5ea6aef169dacf16001972dea04300484bb503785a61b71e41bf9", 0.172, 0.527),
            piece("GreatWave_a3.webp", "897aeb56b0e2c527b02c40d5eeda7c101eebeb3e432770bf89861d9aa0e6414d", 0.172, 0.782),
            piece("GreatWave_b1.webp", "28b72a3a9eb6e798eecfda187705e1e56955a5e19b18006a0b33aed8ca48aff3", 0.355, 0.212),
            piece("GreatWave_b2.webp", "342fea36ea63073282803f7e36fe770b5d8e2f1906c512e19c24af9e68426915", 0.404, 0.468),
            piece("GreatWave_b3.webp", "6b6837959b9ab7e89a689be1ebdcea8b53edb52e5b4f974953b5b7dc50b13b2e", 0.404, 0.752),
            piece("GreatWave_c1.webp", "67422ca616ef0395aac3b3fa5acba56d4aa6a0e0e1efee40f33a75177966b723", 0.617, 0.242),
            piece("GreatWave_c2.webp", "6679166308a66aa4ab4c0d3633838074a0e322ae40486b2a16e5cfa347922eff", 0.64, 0.497),
            piece("GreatWave_c3.webp", "af0f79b1302665cd5e6c0a83de694409c26a6d132a09bee57b4e91f7b3ac34b6", 0.64, 0.752),
            piece("GreatWave_d1.webp", "8ce5241159d5e659e14f223caefa369ce625696cc0e35a66bc0052f124cd0fcb", 0.847, 0.212),
            piece("GreatWave_d2.webp", "5d457790ea88e216813ec4405086ebf8883c657c7061148edfe565458a04b1c4", 0.847, 0.468),
            piece("GreatWave_d3.webp", "2491c11e9208b6b2161acd95cb9eb646f88184f48ae6bae88119221406141a82", 0.847, 0.752),
        ],
    },
    Painting {
        key: "cassatt",
        title: "Mary Cassatt, Summertime (1894)",
        pieces: &[
            piece("cassat_summertime_1.webp", "12250ef3b55af74fc45b2c3597d9bf4d02675650abdbc8bf0885635704065e16", 0.211, 0.244),
            piece("cassat_summertime_2.webp", "d17de55174fa12b04db04b0bfed25d9176ce912e643b1fe1dce31532eec7eb7f", 0.496, 0.244),
            piece("cassat_summertime_3.webp", "13f4baa81dc32bec7494b524d551736acbaa99e7f6d9ab233ba6f90dc71814f6", 0.779, 0.244),
            piece("cassat_summertime_4.webp", "48ada16b2b17e20e74875cb429374c2af58d0c43c0b881d9f941c91e15e96478", 0.211, 0.671),
            piece("cassat_summertime_5.webp", "3d3cc54575c97fc4fc451ea5e65aa40ecb7c762ed2b0632fd4d44dc42ad9f62f", 0.496, 0.673),
            piece("cassat_summertime_6.webp", "a9eb351191253246cd20c5c619e9f699747a547f881bf17f3341dca4cacb8d76", 0.779, 0.673),
        ],
    },
    Painting {
        key: "bazille",
        title: "Frédéric Bazille, The Ramparts at Aigues-Mortes (1867)",
        pieces: &[
            piece("bazille_rampart_1.webp", "6a16546cd624d715e7c9f29133f0667bb4e07a035ebaafb5c392f6811c30cd52", 0.212, 0.283),
            piece("bazille_rampart_2.webp", "365fd7e758887e5aa6390c067e57773e0e5aaff6038436dcb86c1d40c08e25bb", 0.501, 0.283),
            piece("bazille_rampart_3.webp", "1c0393db1da6c10eabac5b1935068e64836a6d9724b010daa51cbdbde02b32b2", 0.791, 0.283),
            piece("bazille_rampart_4.webp", "3508ea1d28bcbc3e34ef11013e73c587c81608e74649b5efd4b2f3d20da1dc0e", 0.212, 0.634),
            piece("bazille_rampart_5.webp", "80bf7e3bd9552d8f1df5b66e5f2936856a9bc9d8f96d0d530f7b4e2dc2869577", 0.501, 0.634),
            piece("bazille_rampart_6.webp", "7f0d19fc2fa3260ed976ee209bd5a1a5d3fe373e936e5d2451d864682a9d5f4a", 0.791, 0.634),
        ],
    },
];

/// `$SNERF_STYLES`, else `${XDG_CACHE_HOME:-$HOME/.cache}/snerf/styles` (as setup-styles.sh).
pub fn styles_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("SNERF_STYLES").filter(|d| !d.is_empty()) {
        return PathBuf::from(dir);
    }
    let cache = std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty()).map(PathBuf::from).unwrap_or_else(|| {
        let home = std::env::var_os("HOME").map(PathBuf::from).unwrap_or_else(|| ".".into());
        home.join(".cache")
    });
    cache.join("snerf").join("styles")
}

/// The painting with this key.
pub fn by_key(key: &str) -> Result<Painting> {
    PAINTINGS.iter().copied().find(|p| p.key == key).with_context(|| {
        format!("no painting {key:?}; known: {}", PAINTINGS.iter().map(|p| p.key).collect::<Vec<_>>().join(", "))
    })
}

/// A `--style` argument: `painting:KEY` is the assembled painting (installed on first use),
/// anything else a file path, returned as it is.
pub fn resolve_style(arg: &Path) -> Result<PathBuf> {
    match arg.to_str().and_then(|s| s.strip_prefix(STYLE_PREFIX)) {
        Some(key) => path(&styles_dir(), &by_key(key)?),
        None => Ok(arg.to_path_buf()),
    }
}

/// Bytes of an installed piece in `dir`, its SHA-256 verified. Errors name the file and say
/// how to install it.
pub fn verified_piece(dir: &Path, piece: &Piece) -> Result<Vec<u8>> {
    let path = dir.join(piece.file);
    let bytes = std::fs::read(&path).with_context(|| format!("{}: painting not installed; run `{SETUP_COMMAND}`", path.display()))?;
    let got = format!("{:x}", Sha256::digest(&bytes));
    if got != piece.sha256 {
        bail!("{}: SHA-256 {got}, expected {}; run `{SETUP_COMMAND}` again", path.display(), piece.sha256);
    }
    Ok(bytes)
}

/// Whether every piece of every painting is installed in `dir` (presence only).
pub fn all_installed(dir: &Path) -> bool {
    PAINTINGS.iter().all(|p| p.pieces.iter().all(|q| dir.join(q.file).is_file()))
}

/// The whole painting from its verified pieces: each piece drawn with its top-left corner at
/// `round(centre − size / 2)` on the board (how the puzzle lays a solved piece), then the
/// picture cropped to the rectangle whose every border row and column is at least 99%
/// covered (the board's outline is ragged by a pixel or two where tabs meet the edge).
/// Errors if a pixel inside that rectangle is still uncovered.
pub fn assemble(dir: &Path, p: &Painting) -> Result<image::RgbImage> {
    let mut placed = Vec::with_capacity(p.pieces.len());
    for q in p.pieces {
        let bytes = verified_piece(dir, q)?;
        let img = image::load_from_memory(&bytes).with_context(|| format!("{}: not a readable image", dir.join(q.file).display()))?.to_rgba8();
        let x0 = (q.x * BOARD.0 - img.width() as f64 / 2.0).round() as i64;
        let y0 = (q.y * BOARD.1 - img.height() as f64 / 2.0).round() as i64;
        placed.push((x0, y0, img));
    }
    let left = placed.iter().map(|(x, _, _)| *x).min().unwrap_or(0);
    let top = placed.iter().map(|(_, y, _)| *y).min().unwrap_or(0);
    let right = placed.iter().map(|(x, _, i)| x + i.width() as i64).max().unwrap_or(0);
    let bottom = placed.iter().map(|(_, y, i)| y + i.height() as i64).max().unwrap_or(0);
    let (w, h) = ((right - left) as usize, (bottom - top) as usize);
    let mut rgb = vec![0u8; w * h * 3];
    let mut covered = vec![false; w * h];
    for (x0, y0, img) in &placed {
        for (x, y, px) in img.enumerate_pixels() {
            if px[3] >= 128 {
                let i = (y as i64 + y0 - top) as usize * w + (x as i64 + x0 - left) as usize;
                rgb[i * 3..i * 3 + 3].copy_from_slice(&px.0[..3]);
                covered[i] = true;
            }
        }
    }
    let (mut x0, mut x1, mut y0, mut y1) = (0usize, w, 0usize, h);
    let row = |y: usize, x0: usize, x1: usize| (x0..x1).filter(|&x| covered[y * w + x]).count() as f64 / (x1 - x0) as f64;
    let col = |x: usize, y0: usize, y1: usize| (y0..y1).filter(|&y| covered[y * w + x]).count() as f64 / (y1 - y0) as f64;
    while x1 - x0 > 2 && y1 - y0 > 2 {
        let edges = [row(y0, x0, x1), row(y1 - 1, x0, x1), col(x0, y0, y1), col(x1 - 1, y0, y1)];
        let (k, least) = edges.iter().copied().enumerate().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        if least >= 0.99 {
            break;
        }
        match k {
            0 => y0 += 1,
            1 => y1 -= 1,
            2 => x0 += 1,
            _ => x1 -= 1,
        }
    }
    let holes = (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).filter(|&(x, y)| !covered[y * w + x]).count();
    if holes > 0 {
        bail!("{}: its {} pieces leave {holes} pixels uncovered; the package's pieces have changed", p.key, p.pieces.len());
    }
    let mut out = image::RgbImage::new((x1 - x0) as u32, (y1 - y0) as u32);
    for (x, y, px) in out.enumerate_pixels_mut() {
        let i = (y as usize + y0) * w + x as usize + x0;
        px.0.copy_from_slice(&rgb[i * 3..i * 3 + 3]);
    }
    Ok(out)
}

/// `dir/KEY.png`, the whole painting, assembled from the verified pieces and written
/// (temp file, then rename) when it is missing or differs from what the pieces give.
pub fn path(dir: &Path, p: &Painting) -> Result<PathBuf> {
    let out = dir.join(format!("{}.png", p.key));
    let img = assemble(dir, p)?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).context("encoding the painting as PNG")?;
    if std::fs::read(&out).ok().as_deref() != Some(png.as_slice()) {
        // a name of our own per process and thread, so parallel tests never share a temp file
        let tmp = dir.join(format!(".{}.{}.{:?}.tmp", p.key, std::process::id(), std::thread::current().id()));
        std::fs::write(&tmp, &png).with_context(|| format!("{}: cannot write", tmp.display()))?;
        std::fs::rename(&tmp, &out).with_context(|| format!("{}: cannot write", out.display()))?;
    }
    Ok(out)
}
