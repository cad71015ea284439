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

/// At most this many pixels inside a painting may be left uncovered by its pieces (seams).
const MAX_SEAM_HOLES: usize = 4;

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
/// measured on; the last three were added later as held-out styles (docs/stylize-notebook.md §5j).
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

/// Fifteen more works from the same package, none of which any default or metric was
/// chosen on: the held-out styles of `snerf bench style-metric` (docs/stylize-notebook.md §5m). Positions
/// from the package's `board2_0.qml` … `board17_0.qml` (boards 2–6 and 8–17; board 18,
/// Renoir's *Girls at the Piano*, leaves holes between its pieces and is left out). One
/// is a photograph of a sculpture, not a painting; it stays, as a style a user may well try.
pub const HELD_OUT: [Painting; 15] = [
    Painting {
        key: "durer",
        title: "Albrecht Dürer, Lion (1494)",
        pieces: &[
            piece("AlbrechtDurer_a1.webp", "a292cce2c1682166222864b7ee8ec4bb31e1074ae679505b325276ea06870698", 0.156, 0.138),
            piece("AlbrechtDurer_a2.webp", "e007e72459059688ee2921dfee7a21a874ad96fb20ab6daf58532ac2b7b4291a", 0.156, 0.377),
            piece("AlbrechtDurer_a3.webp", "60963024b7cd0a0ae9bcaed5dad657d1e17ea0014cfd157e1a933a077110827d", 0.13, 0.617),
            piece("AlbrechtDurer_a4.webp", "261e5a9fe93613bfbe16d58a5eb8d417c69514afbab3210c6f0813eb666c84a3", 0.13, 0.831),
            piece("AlbrechtDurer_b1.webp", "7038e54836a10269cdb3d19d328bced8c63e1d1aa1495ef7f5f0e5c7b166eff8", 0.4, 0.163),
            piece("AlbrechtDurer_b2.webp", "30461725e628e1adc4fa72ea384f2465f6fe53d64401ab4146b83e93eca07d59", 0.374, 0.4),
            piece("AlbrechtDurer_b3.webp", "f118cc75e951a076b11920edab9f8976bd8f5e2496c179bbfd7cb5dffe608898", 0.349, 0.643),
            piece("AlbrechtDurer_b4.webp", "bc6ab53107a64f33f630a5f5dcee2c1d886b4f258a099958c41a1d533c81336a", 0.349, 0.854),
            piece("AlbrechtDurer_c1.webp", "1d2aebe5c52769a2810372f0248b76770c1306ac88f53044e294eff9d9181248", 0.647, 0.163),
            piece("AlbrechtDurer_c2.webp", "070a33a9a22da13d7a16158606c355d31886f0dd5d54f33790b0133f2d36b72b", 0.623, 0.376),
            piece("AlbrechtDurer_c3.webp", "ecc045d92cee52bdbf308dc5fa498a6c5948d80b56c43297cb2f99ee5dd280b8", 0.597, 0.594),
            piece("AlbrechtDurer_c4.webp", "da868de1f7a7555d6c6d84f920c91862e0ef2297b3a5ad411247019c39b93348", 0.623, 0.831),
            piece("AlbrechtDurer_d1.webp", "d32da7662a6eb9993fa1c30fcc90e6e6b87110fd919baee499fc7ffb2de8e303", 0.864, 0.163),
            piece("AlbrechtDurer_d2.webp", "5b6642166d8ad05fe74811c3638184816df77a1e871e201fc98dd76f67e12ff9", 0.864, 0.4),
            piece("AlbrechtDurer_d3.webp", "8d69022ed5b733c2ed34d4aaec851e8b6b3000ba6e73593df2d6d669745f90cc", 0.839, 0.617),
            piece("AlbrechtDurer_d4.webp", "bf2e288c9f788b0d1d030219555935e569d8d9ee046528c6a0ee8c1dd3d5d75e", 0.864, 0.831),
        ],
    },
    Painting {
        key: "librarian",
        title: "Giuseppe Arcimboldo, The Librarian (1566)",
        pieces: &[
            piece("Arcimboldo_Librarian_a1.webp", "8f16256d00a6aa72fac43eb9314d6d3939c86da9c5725d5324918984f49c8e03", 0.373, 0.231),
            piece("Arcimboldo_Librarian_a2.webp", "5babf15b69e6de78cfe550909ca1b2f3c84da3179c42bb1d47feea6d48d3ea02", 0.357, 0.498),
            piece("Arcimboldo_Librarian_a3.webp", "c8d854f65cd46de7ed4d388bb90400fe7f0d3d4648474f06dc746caf7f056a0f", 0.372, 0.762),
            piece("Arcimboldo_Librarian_b1.webp", "3677e336ee84b61d76bb17e7b58c37207df0d2d3db8eccda002a1c32bb2129e2", 0.498, 0.259),
            piece("Arcimboldo_Librarian_b2.webp", "86b561e2bd2c307b8763cc8779482ba8a7bb26b81dd697134d2b3676e33dc5fd", 0.499, 0.497),
            piece("Arcimboldo_Librarian_b3.webp", "93f1b57af348d15fa777c31d698fb95c31f665689333e6e1aea73d69cbd00aec", 0.498, 0.735),
            piece("Arcimboldo_Librarian_c1.webp", "d8038e0e9788114b71898bf74be85c8c942188f9b94fbf78c711d62889eedbac", 0.625, 0.231),
            piece("Arcimboldo_Librarian_c2.webp", "a96e265f96a59c800ce1cbc09694931bbd85c0089a332168bb6cbddcddc3ca76", 0.638, 0.47),
            piece("Arcimboldo_Librarian_c3.webp", "ad960a4bc066f536d153913bcec7cafc7bbef13af3796e81642d43a3810b1900", 0.625, 0.735),
        ],
    },
    Painting {
        key: "spring",
        title: "Giuseppe Arcimboldo, Spring (1573)",
        pieces: &[
            piece("Arcimboldo_Spring_a1.webp", "37816ac81d9d517d04fb88fc728b44d2b100bb5f8406d044ac812708ea29ce53", 0.379, 0.259),
            piece("Arcimboldo_Spring_a2.webp", "59474f5f0d8ad946a307f9520b8ea4c31823e9f88f1937cf410fbb667a78f5a2", 0.379, 0.497),
            piece("Arcimboldo_Spring_a3.webp", "c3f20dc47e9b20108bf892c5173f01668538f21ed846874c635f2496b3b1e956", 0.405, 0.735),
            piece("Arcimboldo_Spring_b1.webp", "a80854a1d38839837ee56b594725c3ebc6a3d2ac8e0259aefdcd29d4ce45644c", 0.59, 0.231),
            piece("Arcimboldo_Spring_b2.webp", "752dd5271e3d6600064a507f555764a5b432794e2426be7bac39e366a198c250", 0.59, 0.498),
            piece("Arcimboldo_Spring_b3.webp", "d36caa189e3e7223ac8de440b6c47a5a703d17072499b0da29a4104db21224bd", 0.615, 0.762),
        ],
    },
    Painting {
        key: "ejiri",
        title: "Katsushika Hokusai, Ejiri in Suruga Province (1830-1833)",
        pieces: &[
            piece("EjiriSuruga_a1.webp", "6724ed375ba4023e3b35f6a3bd072242dd97199e2363b1b6779c357378e7e0f5", 0.174, 0.212),
            piece("EjiriSuruga_a2.webp", "6962d5c9069baf4ea5ab2d9c4d525c9ae3ed62c78bbc1d76427d884590fbeff7", 0.174, 0.498),
            piece("EjiriSuruga_a3.webp", "a7f838dac1d7193c2cce3b481554f110140141da966b0c66c3199f917254ec78", 0.174, 0.782),
            piece("EjiriSuruga_b1.webp", "313c87d521494ef6d80464bb8f783c6b4eab7eec3ddf7b42662011c2ee6ca17c", 0.405, 0.212),
            piece("EjiriSuruga_b2.webp", "9eb22f44d6270400d4e995ba82e10acfee7ec504a406bc5f8453578f4b49bd6f", 0.405, 0.468),
            piece("EjiriSuruga_b3.webp", "4be5a6f974b6e88212bb523a48b768d8710bd716749c92a00f85a079382bd83c", 0.38, 0.752),
            piece("EjiriSuruga_c1.webp", "a2a52da406ccc97a6efc36a411e48711709decf11814c78f2b36cf8fd623f68e", 0.616, 0.212),
            piece("EjiriSuruga_c2.webp", "42ae57a5766d4aff7a1c2ae7a61690a5cd9307edddd96d1fb724ff398871be43", 0.616, 0.468),
            piece("EjiriSuruga_c3.webp", "b7f075c282f76a62398e491ca44c9e28121823641217dd6137b7417e7365dd69", 0.618, 0.752),
            piece("EjiriSuruga_d1.webp", "4263ff3c20a012301319106bd54c9de3b76cd25caa82a134c4bd9fabea7f25ab", 0.823, 0.242),
            piece("EjiriSuruga_d2.webp", "373334f1546d99b9218e663afb8a6b00d30319a696894596f3be5865c9672ef2", 0.823, 0.497),
            piece("EjiriSuruga_d3.webp", "935764a4b0acd0a00c35f15dea04f9ee324dcdd87f71f5c0e08619f1adf57694", 0.846, 0.752),
        ],
    },
    Painting {
        key: "ryogoku",
        title: "Katsushika Hokusai, Viewing Sunset over the Ryogoku Bridge from the Ommaya Embankment (1830)",
        pieces: &[
            piece("HokusaiBridge_a1.webp", "ff553c4faaca60b322c970de9048931fcd2be71e144d58351c8d5303150d4931", 0.125, 0.197),
            piece("HokusaiBridge_a2.webp", "d9cb7b5a9bd7681234b8c57d9bbaf9abff88075c36b222ba00b4e1e1cfe65e97", 0.125, 0.388),
            piece("HokusaiBridge_a3.webp", "1eb2ac8ccc2ef4ce41a7b6b81ae730d7f62ba4cbf600f70fa425c8724b29db46", 0.145, 0.585),
            piece("HokusaiBridge_a4.webp", "a3cb33e52382a75dc914c7386dbb304187b4929d920627c52cc1d4e8ffe975d3", 0.125, 0.798),
            piece("HokusaiBridge_b1.webp", "7b2195ec825490bd8166024166ce759566e94b8d2b81bf42e6c6e7ee8825d4c7", 0.311, 0.197),
            piece("HokusaiBridge_b2.webp", "6b645ec543e0d44a6908d65cb50460f9095dce6acde8f8d76f010723de3e9395", 0.291, 0.388),
            piece("HokusaiBridge_b3.webp", "7dda1c169096173477fae465a8ebe7ef2e11fd2374e359400f802626d8a07265", 0.309, 0.609),
            piece("HokusaiBridge_b4.webp", "78ff680b3a26989a73c793b63c3a3e80705908815b577a993d4e2ca898e5725c", 0.311, 0.819),
            piece("HokusaiBridge_c1.webp", "0a3ff017c67357e4288a66a942808a0e7d62abe8380c35879094c19117e0bae0", 0.517, 0.174),
            piece("HokusaiBridge_c2.webp", "0e73560a33649ca0639197aa4d94aa37071fc88a506e4ab153bdcd1828d883bc", 0.479, 0.39),
            piece("HokusaiBridge_c3.webp", "f622cf4b3b074d366f141cf545dd98050ab38813311d1b19ab93a7fe63c8c19b", 0.479, 0.63),
            piece("HokusaiBridge_c4.webp", "f3a0ef87a1c611a5516fcd7571795b6c90ddc8c94ef4b112a968ee2ff847b33d", 0.497, 0.819),
            piece("HokusaiBridge_d1.webp", "977cd3b8efe03e5321d935d2b055b947ce4b614cef99f64fc0db2e35a45a60dd", 0.705, 0.197),
            piece("HokusaiBridge_d2.webp", "f7d4f54dd113b020f4704ac8db9a287739184dc7ab91cd16cb17bb9545c54bf0", 0.687, 0.412),
            piece("HokusaiBridge_d3.webp", "6909eb7879b0784e0d7afc6e293d850e39dcebe9315981a1ca9979d3eed9e148", 0.687, 0.607),
            piece("HokusaiBridge_d4.webp", "1687414c0a224ec7a5451d8fb453853c578c93849cf2c0e3669f3ce1b02422ce", 0.687, 0.798),
            piece("HokusaiBridge_e1.webp", "02c8ec3848e046ce02f255152d4e319ad044ebbaafef7f5add8dd564718e4f8a", 0.869, 0.197),
            piece("HokusaiBridge_e2.webp", "26d60496b23a78c7691dcbeb070796f1f8a6ad15feae293e31c4ea9db1d13bca", 0.869, 0.388),
            piece("HokusaiBridge_e3.webp", "4042c89b677f26b6e796dffbef90d70f63bf9189a46f3c6d255f9f853d88e601", 0.869, 0.585),
            piece("HokusaiBridge_e4.webp", "35c2888093c5b214a59f37eceae9e1444bd05c8825e8eac0ae28ea87b75fadb4", 0.869, 0.798),
        ],
    },
    Painting {
        key: "oiran",
        title: "Katsushika Hokusai, Oiran and Kamuro",
        pieces: &[
            piece("HokusaiOiranKamuro_a1.webp", "d029151c03f2dca9d79fc8c041a6fae488569ae73c3086ca01a7039766687494", 0.416, 0.242),
            piece("HokusaiOiranKamuro_a2.webp", "f599ebd4f80f62d98424b2574f97d909f60f94ab7272652c95951712fa86980c", 0.416, 0.497),
            piece("HokusaiOiranKamuro_a3.webp", "3e939f83be171528129ad518f74c3e19e128b1ad4178de418e72f61d914a9081", 0.416, 0.752),
            piece("HokusaiOiranKamuro_b1.webp", "846f1d8a287cfa00f323d5732a4b4110ce70b925721804668641231dbb73e9f6", 0.602, 0.242),
            piece("HokusaiOiranKamuro_b2.webp", "07ad84266dc3a21181143728046bff6e09207a2cd46220342e11a1388e924e2d", 0.602, 0.497),
            piece("HokusaiOiranKamuro_b3.webp", "c05d52c7194a997f8c77e5273f61432ae549ca6bf113c358b7a7c9cb7fbc2079", 0.602, 0.752),
        ],
    },
    Painting {
        key: "poppies",
        title: "Katsushika Hokusai, Poppies (1833-1834)",
        pieces: &[
            piece("HokusaiPoppies_a1.webp", "4429080ec009e12177fe8bbc70188ca7fce66342d139519b1d711e787488d776", 0.127, 0.169),
            piece("HokusaiPoppies_a2.webp", "838bd3a3645b7ad6805188834e934f83b540c99df4a1cee4075e037607b520f4", 0.147, 0.34),
            piece("HokusaiPoppies_a3.webp", "7d1f6fd3263b0145b4bdf1b39993cbe10c8cd0aa55ca408f6b8c30a57da4b24d", 0.147, 0.496),
            piece("HokusaiPoppies_a4.webp", "25b9e000e63b2aea42dc55702569c23daf8127be2e6b799196354df4f02df5e9", 0.147, 0.654),
            piece("HokusaiPoppies_a5.webp", "cbb34e88c7d9a1ffd6ca9d060f19be83747b7f83ee2ac8b4865f75350b9dc85f", 0.127, 0.825),
            piece("HokusaiPoppies_b1.webp", "460c026dced7c7917f0df7ce9abb77a7829c97b82e3655acf84a8b63a80c6edb", 0.311, 0.15),
            piece("HokusaiPoppies_b2.webp", "be15848d5619e5301ba85a48ea2e187eee890ba02b8663fda3c947d2aec1987f", 0.329, 0.305),
            piece("HokusaiPoppies_b3.webp", "db86e75e1f1fd249bac93c88da90080c233ffd49474746213c38c3ca69cac118", 0.31, 0.498),
            piece("HokusaiPoppies_b4.webp", "f9431bf57205090c99eb85c533aa2f036213f14538ee5a1884d843da1265ce9d", 0.31, 0.689),
            piece("HokusaiPoppies_b5.webp", "d43420d2c2394d2b7c9ec3584f22997bad4e16d8407e44264659fbf852629ceb", 0.311, 0.842),
            piece("HokusaiPoppies_c1.webp", "9ff12143f4e5fcee6f9c9edc9253b413de05d8cbdcab417a5cac8865b8b083c6", 0.516, 0.15),
            piece("HokusaiPoppies_c2.webp", "60d00670f6ca740cdced726f9a10f659ae829277583ae615548e187b14ac6f14", 0.516, 0.323),
            piece("HokusaiPoppies_c3.webp", "f1873868fba6e3232bab5193ee6594ce168817240a156086ac0236375282e2d3", 0.498, 0.496),
            piece("HokusaiPoppies_c4.webp", "94fb8ef6dc493af08e00de11d82808472b384df3761fe6cde68a9b20675b2b8f", 0.498, 0.673),
            piece("HokusaiPoppies_c5.webp", "b7aa660c193c286a02481a0f9cfaca509d81a9ef10871c7a911ce960895dac5b", 0.496, 0.842),
            piece("HokusaiPoppies_d1.webp", "3562fee279e1287e1004371f4c612a8ff99717419ce6bed94202dd8ee450ff71", 0.702, 0.169),
            piece("HokusaiPoppies_d2.webp", "4a2a05c61c47ad793664bfea734a9623456560d35d297638c228f9dcbd89161c", 0.683, 0.34),
            piece("HokusaiPoppies_d3.webp", "2d45583c32ed518441d2e57a656b74688f7f73e238036e3b1edd6a460e398423", 0.702, 0.515),
            piece("HokusaiPoppies_d4.webp", "86e1a6fe6cd4a60c00a207e3a1693227d0442f2c7bbd340e48636489379b00ce", 0.702, 0.671),
            piece("HokusaiPoppies_d5.webp", "adfc8189b45167b0b0761ff1034f4fd62db9bdb3cc172add3190da0bf1bdd425", 0.665, 0.825),
            piece("HokusaiPoppies_e1.webp", "c4e8a35bac187c29b4696d26c3d5d1c3f1f4a6aba5be14e29c7af789ad3eeeba", 0.865, 0.169),
            piece("HokusaiPoppies_e2.webp", "005d8a14b7974a4b84d7a8a67b5d9a7be2858cfe37a37e22bbd40486948f1363", 0.848, 0.34),
            piece("HokusaiPoppies_e3.webp", "be19874c7b5fef8fbcebd424216706e7a73355d1a3f5ff71d04caaf78b4b1ec2", 0.865, 0.515),
            piece("HokusaiPoppies_e4.webp", "35840c5f1dfe722ef3e70cc4bbe1ca8529e52e91451538a6667c99d2a7e9eaf5", 0.865, 0.671),
            piece("HokusaiPoppies_e5.webp", "492461ac3274c661f1c120b210483e112ca0691c9fa32b1e6004a3429b6a1a23", 0.848, 0.825),
        ],
    },
    Painting {
        key: "fan",
        title: "Katsushika Hokusai, Woman Holding a Fan",
        pieces: &[
            piece("HokusaiWomanHoldingFan_a1.webp", "a04cc510c0168864cbed71a5af3c27ccae560f221b39a08dfa6fc32697e70b7c", 0.355, 0.212),
            piece("HokusaiWomanHoldingFan_a2.webp", "7e7e7384e1da5e155c24c5f2c6b9cee698ea2efedbea73c9472b9273b48811b5", 0.355, 0.498),
            piece("HokusaiWomanHoldingFan_a3.webp", "2c23573129e588d66adbdab29f10ea22c9dcf3d5df327797d745e328536f0cc1", 0.355, 0.782),
            piece("HokusaiWomanHoldingFan_b1.webp", "b75413b0d1912bb17a39eaf11f6922e1654c0ce762e24b1968d3d364f9c78ed7", 0.499, 0.242),
            piece("HokusaiWomanHoldingFan_b2.webp", "9e286bdf6521fe2763bda79c7474fd467598777565b667bdf82021400cbb5fd5", 0.499, 0.497),
            piece("HokusaiWomanHoldingFan_b3.webp", "e6a9b15a57fcd475f0032044e2fdccc932482bd626796d249509699d14bb8bb9", 0.484, 0.752),
            piece("HokusaiWomanHoldingFan_c1.webp", "74271cc15417e3c63eec40ace6deb929b27ab27e4c0b4925a0b9afb7b3e2998e", 0.64, 0.212),
            piece("HokusaiWomanHoldingFan_c2.webp", "fbdb67f4e6c6363afed5662b370c35d88f75806676a0f1ee15c48e5837aa7167", 0.64, 0.468),
            piece("HokusaiWomanHoldingFan_c3.webp", "6920d6eed15a4a8af0096584e3da0f73fea027b0202d5e9beb7970bdb1dc2fc1", 0.627, 0.752),
        ],
    },
    Painting {
        key: "kazusa",
        title: "Katsushika Hokusai, Kazusa Sea Route (1830)",
        pieces: &[
            piece("KazusaSeaRoute_a1.webp", "729156dfa1854f3aa02d02f7fd75310ece0c512898bf9f291524a08927dfcaea", 0.132, 0.15),
            piece("KazusaSeaRoute_a2.webp", "d0ea523d71c3d7c8a36dfa830c843dfb6954a890b125d4ef26a93ded5abe08fb", 0.113, 0.305),
            piece("KazusaSeaRoute_a3.webp", "ad52e2bce20de6a3e91b9164312779a6d38a9f640f5f33f9e9158c6c08d207a6", 0.132, 0.48),
            piece("KazusaSeaRoute_a4.webp", "4a10a7ea07e2cd510be6788e6edc832c1df58c4581a0c2e6a9c6cd30f748ac8f", 0.132, 0.654),
            piece("KazusaSeaRoute_a5.webp", "d829b7d94593a9a031299d54f8bca1f7bec2f94d373981dbde2d1af7131ba07b", 0.132, 0.825),
            piece("KazusaSeaRoute_b1.webp", "e6a8640ff9a97c10bd40ec8e1c37de28c697b102894fa5ca5baa5916489eaaa6", 0.303, 0.15),
            piece("KazusaSeaRoute_b2.webp", "54fbd6f4d994ec7de586ddc471db24731d7db81a8534188179a28c12b35f1538", 0.304, 0.323),
            piece("KazusaSeaRoute_b3.webp", "d8f618c9a46e0af7bf9dbe526e1f948a148c0153cedb45e7020cb8167d6f3416", 0.303, 0.496),
            piece("KazusaSeaRoute_b4.webp", "aaa2b77d254854bb0d800b0f796611a435a5c0ea70ab404af089a314625a76bc", 0.303, 0.654),
            piece("KazusaSeaRoute_b5.webp", "92f1f2d46a66c3b8c44925776b5c3fa4ccb998dbafb772a3cf2b1d8776c331d7", 0.323, 0.825),
            piece("KazusaSeaRoute_c1.webp", "8929cfbc82afa13c0587c655e23ef98ce9ba00cc09af3ade01bb70db8d522d0a", 0.499, 0.15),
            piece("KazusaSeaRoute_c2.webp", "5a7136603b37dc92ba67ddb12e67bb4195534662f77c33a97ee79b3b0fe6513a", 0.499, 0.323),
            piece("KazusaSeaRoute_c3.webp", "997a8bf365d3e214200e4d2939f6e5545c12afb1e975ffc259559d893be713c1", 0.499, 0.515),
            piece("KazusaSeaRoute_c4.webp", "5027a99e7365e030e75ced0eabcfc486bf0bc07b22fd9c64b0ea172a7599f009", 0.499, 0.689),
            piece("KazusaSeaRoute_c5.webp", "b2a6d7711eb0b045ecc48b12cf170f3d61be02658172fe6ba391cdeb78cc534f", 0.519, 0.842),
            piece("KazusaSeaRoute_d1.webp", "549481f44aab521512771d7f8014297c88e04f352ffefe51808bfb4571c57ea3", 0.713, 0.169),
            piece("KazusaSeaRoute_d2.webp", "dfb42e5ea7d4f373dc7a8cc1ece9ca178cdec9037c613bac260fd9046a5c3875", 0.694, 0.34),
            piece("KazusaSeaRoute_d3.webp", "1a46b08c01d1d7284596a111b714c1d56497e8e9513da9757b167d77e5d3751c", 0.713, 0.515),
            piece("KazusaSeaRoute_d4.webp", "2194cdcfce80e79f180d1c5bf93a7fc2decb918c1e99c9bb8139047b58981e91", 0.693, 0.671),
            piece("KazusaSeaRoute_d5.webp", "b68d8e2223e0cff32fa26b4191e799870be6befa054ab5d5b3ebbe7529be6188", 0.693, 0.825),
            piece("KazusaSeaRoute_e1.webp", "70f16be009e4d60dcbda6fdc69962c8a8207ecad6af76a70154e860f76ac2e0b", 0.882, 0.169),
            piece("KazusaSeaRoute_e2.webp", "095c66fe5f60dd3d7aa5a329e203102558e3829a4310b0635cc91518dfff21f8", 0.882, 0.321),
            piece("KazusaSeaRoute_e3.webp", "d8a530146d05222872efe2ad4d84d202436933507fac7972f5a23801a9b36df9", 0.882, 0.498),
            piece("KazusaSeaRoute_e4.webp", "001cef5bb080882b0e2b0a87c40ca5bb3d491795519da4b38804edf74f0b5a48", 0.863, 0.689),
            piece("KazusaSeaRoute_e5.webp", "7104aba7395158a6f1e0c8866092c910f3d544e918667352a01c617e1aa64498", 0.863, 0.842),
        ],
    },
    Painting {
        key: "prawns",
        title: "Utagawa Hiroshige, Horse-mackerel and Prawn (1840)",
        pieces: &[
            piece("HiroshigeHorsePrawns_a1.webp", "d3e4fed4b834b8da745d5e60f29e498e7db50729d3032da79d575fa75fd36c12", 0.142, 0.163),
            piece("HiroshigeHorsePrawns_a2.webp", "c0db7637115ae575485d59a27e691e285d256dd7b5c0267173d2e47e3d90af12", 0.142, 0.375),
            piece("HiroshigeHorsePrawns_a3.webp", "f13541b652185026bd82b582630e75939cfafcdc2d97546262f315e66879971e", 0.115, 0.594),
            piece("HiroshigeHorsePrawns_a4.webp", "720bf2681396202048a21b12f113d69cceb884f879e515db16d60da2151ded3a", 0.115, 0.83),
            piece("HiroshigeHorsePrawns_b1.webp", "1d5f568ec9a1d9d3715194bbd10ea5d30a5cb0a24e87a4812e68f5063d2a9cf2", 0.368, 0.163),
            piece("HiroshigeHorsePrawns_b2.webp", "f46dc06baf61f3380249f1bf0d421d4d1f04df0d733e1841e6e54b848b3f6fa0", 0.368, 0.4),
            piece("HiroshigeHorsePrawns_b3.webp", "68cd13342da1a172af4bf05aa8556e3100ba169ef66d74ee2b1d84def602a5f9", 0.343, 0.617),
            piece("HiroshigeHorsePrawns_b4.webp", "3d6836e50e0ba1d67a83a9a1df9cfb6e1dd613d2170fc6311386ef8fa85f1258", 0.37, 0.83),
            piece("HiroshigeHorsePrawns_c1.webp", "879fbd0001d1a7bc8c8a059c6eaeb151fcda1bfcb2f71c33b5535d6ee5dae171", 0.627, 0.163),
            piece("HiroshigeHorsePrawns_c2.webp", "443c7f3d4a3eda6c4fc62f96ab668b1f8f55d6a5bedf24c2452391b133c6906a", 0.6, 0.376),
            piece("HiroshigeHorsePrawns_c3.webp", "22f7e5e08c501edf3ccb30c234243cb876b8a7a40e1da070828b2d46bd9f567e", 0.6, 0.619),
            piece("HiroshigeHorsePrawns_c4.webp", "7ede434ec087710a641f07c32159c0a3e6da642e2001cedb1c55b80fe6f24e86", 0.626, 0.853),
            piece("HiroshigeHorsePrawns_d1.webp", "32d63c7b0240014a8b967c091f982c89540d1ab6988ebce2894fbcaa138ab867", 0.878, 0.163),
            piece("HiroshigeHorsePrawns_d2.webp", "17c05791c8084c4a41813dcb2f8a9b3b2cf266dd4fedeee5436597fbdf0e6886", 0.853, 0.376),
            piece("HiroshigeHorsePrawns_d3.webp", "93dbeaab7ac3a9d6bf166b61ff96646b9e36c1e36817309e0a96714fa1ec73d8", 0.853, 0.594),
            piece("HiroshigeHorsePrawns_d4.webp", "7a50fec6cb7e7a7b7ad31d9c9c0960f186b44518b962924e224bd16d3bc30a7b", 0.853, 0.83),
        ],
    },
    Painting {
        key: "inokashira",
        title: "Utagawa Hiroshige, The Benzaiten Shrine at Inokashira in Snow",
        pieces: &[
            piece("HiroshigeInokashiraSnow_a1.webp", "8463228c567235064268b1b81d4652183e87e18836d7300c736a2d2a040c5c11", 0.129, 0.197),
            piece("HiroshigeInokashiraSnow_a2.webp", "805c567a58c7339fc845383bec18b74b6d8e6d8eae0d29bdf87caa6b7bfb52d2", 0.129, 0.388),
            piece("HiroshigeInokashiraSnow_a3.webp", "701f3f2437126a34188532470648362f862fce22c9a467ba4eaa221898fd1fee", 0.155, 0.609),
            piece("HiroshigeInokashiraSnow_a4.webp", "fe06c9f2f645ad77106cd558da61cf70f97589970381ff8e0606a4f3e2a0759e", 0.129, 0.819),
            piece("HiroshigeInokashiraSnow_b1.webp", "78a178688f18f793215c5e52f38f4e9405ba0bf81a4e54dcbf5cbba180ef0e2c", 0.348, 0.197),
            piece("HiroshigeInokashiraSnow_b2.webp", "cb9b7230efae1566d0de2067b14b6ebd294890f43a95267ef6814e893e3f6424", 0.348, 0.412),
            piece("HiroshigeInokashiraSnow_b3.webp", "d285b08d007b79e795a9a2179429ab96dc99788483a08d988c2421b037ccf29e", 0.373, 0.63),
            piece("HiroshigeInokashiraSnow_b4.webp", "3cf0972da5053035b1324764caaf39619a9583862eab0d44b64e03afccb74347", 0.374, 0.819),
            piece("HiroshigeInokashiraSnow_c1.webp", "570c68c96a9d8229a78aae2914f51a39544ca08e36327f2e18cbb642b5b35752", 0.598, 0.197),
            piece("HiroshigeInokashiraSnow_c2.webp", "755a1e95674b8170d5fc8a3494401e2d503588980098b6df08cd75a0e0a08630", 0.623, 0.412),
            piece("HiroshigeInokashiraSnow_c3.webp", "0cc29f0af5c0d22f78a82431483716b45ef31f4a1e527db60bdd89a0475d9657", 0.623, 0.607),
            piece("HiroshigeInokashiraSnow_c4.webp", "ccf745a5473cf37d457facaf0118caeefdde9fddfffa87fba7faa612a9110388", 0.623, 0.798),
            piece("HiroshigeInokashiraSnow_d1.webp", "908978cf201fad42ecf164e9e812bc553911c23a30fca9f09bf58b167b77cb2c", 0.841, 0.197),
            piece("HiroshigeInokashiraSnow_d2.webp", "b7180f8d1289c9ccff17e7cce71257e0ec265b9caead15972600c2a0b3e27e15", 0.866, 0.388),
            piece("HiroshigeInokashiraSnow_d3.webp", "517fefdb197fcc056ced16bc5edaa7efa14188360413e71e55a332eec8d0e870", 0.866, 0.609),
            piece("HiroshigeInokashiraSnow_d4.webp", "1f4b97256d480585eee37b3c4346354839154435a46ada507d89b0fcb7d3d976", 0.841, 0.819),
        ],
    },
    Painting {
        key: "pieta",
        title: "Michelangelo, Pietà (1499), a photograph of the sculpture",
        pieces: &[
            piece("Michelangelo_Pieta_a1.webp", "ce2723024814aca9fcbfcb7bb88d85c19484165ebf697ee05cf12d6b036c7168", 0.298, 0.138),
            piece("Michelangelo_Pieta_a2.webp", "387740a87d2874c24d9124cd996c9cf96cdf727c76c4d59dc153c246a5510764", 0.275, 0.377),
            piece("Michelangelo_Pieta_a3.webp", "f514549b84a29dcd5f2848709d5777a460e252fed7cca3b40cae54bc9cc67d7d", 0.298, 0.617),
            piece("Michelangelo_Pieta_a4.webp", "a0b380752c44ff9e16730882e33a2c976ac4bbb7ef6c18c3e8e33884b609b6a1", 0.275, 0.831),
            piece("Michelangelo_Pieta_b1.webp", "3dc80e59239e3dad90e3239e104cb8e0d55bae14101521b95f7f63d97320d3cb", 0.497, 0.138),
            piece("Michelangelo_Pieta_b2.webp", "de6acb5e9dca5705a3d6d7a23b5442f170a7a1c237cf275177ed7115495cc2e8", 0.474, 0.352),
            piece("Michelangelo_Pieta_b3.webp", "085be9e34c4c827aa2252629231c510b5901e5f3a64aab4d31abd5f7c35a8819", 0.521, 0.619),
            piece("Michelangelo_Pieta_b4.webp", "34f715a0cf192d2401ffd685c1f5f97fbd6bfb699c5ffac94c7b4af640aa0754", 0.474, 0.854),
            piece("Michelangelo_Pieta_c1.webp", "2eda236b512c8cbe51c50d1176f8975130065640f470aa3e37a7fa6ff131c3b2", 0.696, 0.138),
            piece("Michelangelo_Pieta_c2.webp", "98b253d1dc639bee8ce459cde3b91ef4fc8d92c7a3790ccf27b3a8d313846f90", 0.696, 0.352),
            piece("Michelangelo_Pieta_c3.webp", "94262739463e5e1f41b7d34ddde18088aad4406e8137049909cf84d8afe96cb8", 0.719, 0.619),
            piece("Michelangelo_Pieta_c4.webp", "a2d54ee1764972d9d8d45ca7a56e4802321fe8cc42c96a34642194657a721288", 0.696, 0.854),
        ],
    },
    Painting {
        key: "monalisa",
        title: "Leonardo da Vinci, Mona Lisa (1503-1519)",
        pieces: &[
            piece("MonaLisa_a1.webp", "0d69e4bef885e1d6583160414b3e0bdb9b46e203f6dc1ffe7066075cc3bfec6d", 0.328, 0.214),
            piece("MonaLisa_a2.webp", "c985203d84469032032586bb9dffed326bc45122afd3e5ad258f7e92263c3d6c", 0.34, 0.531),
            piece("MonaLisa_a3.webp", "c982051cf60b1fd92d762bf0453ea6d86153496ffd33f8c9c97f1b45eb512934", 0.328, 0.814),
            piece("MonaLisa_b1.webp", "9d3b46a53a2abce842660564e4826f2af3b3335df07572cdc81aee6f282b7046", 0.442, 0.18),
            piece("MonaLisa_b2.webp", "331eca239b3eeb1b1514a234630dee63baeb722fd7419cdf2c42ac70e75e8115", 0.453, 0.499),
            piece("MonaLisa_b3.webp", "b655a1707b8c25f53173bfe0cd6318217e2877d2fb7a90a630362b85dffc8295", 0.442, 0.814),
            piece("MonaLisa_c1.webp", "83f4abc55c4c06b00223eb2fc616731e09e134e5621cac1fad5922513c587be9", 0.556, 0.18),
            piece("MonaLisa_c2.webp", "3e09d643604d2da186c5b484861dcd7c88d12a114b3b45d57aad80d7db746713", 0.568, 0.499),
            piece("MonaLisa_c3.webp", "ff1a07ecc7e560b4ecb78881754f3aa7520914ebeb9293b88566d77282173f84", 0.568, 0.814),
            piece("MonaLisa_d1.webp", "0d5961d6fd19bd72cd65f67033ad13b6d18cb90768d46d42641ee3194e811cb7", 0.656, 0.214),
            piece("MonaLisa_d2.webp", "6d0add0b76699742def0979aa00910709fed2254daf308a18095b241029fe744", 0.667, 0.497),
            piece("MonaLisa_d3.webp", "97456266057a96e3775e902ee5625a979b19f75998f612bfb596fcc466222f4d", 0.667, 0.782),
        ],
    },
    Painting {
        key: "pesaro",
        title: "Giovanni Bellini, Pesaro Altarpiece (1475-1485)",
        pieces: &[
            piece("PalaDiPesaro_a1.webp", "b74c706b3f043958c50a69edc7b86679b2c63c4714ded93e1dd314820ecc9f71", 0.182, 0.264),
            piece("PalaDiPesaro_a2.webp", "09722459f509290510d1e34a81dd07792c81ace1507d8b815f8d67d85cf2670c", 0.215, 0.474),
            piece("PalaDiPesaro_a3.webp", "b09b5cf104142f528a134a6eb928a867ec9cfd4f9a2751de9dc10b0e0ef4793d", 0.182, 0.705),
            piece("PalaDiPesaro_b1.webp", "94820978adbc91e955bce9a64e8ccdccde27f97fb0524aa51b27b0ff85ea66d5", 0.466, 0.264),
            piece("PalaDiPesaro_b2.webp", "3fab215ad03c9e8237bb10053f3dd1102a26bf21fa3bc2ec43fbd2736f021181", 0.532, 0.498),
            piece("PalaDiPesaro_b3.webp", "66471a5d68b3cae0f1c5863acecf27f84c2137fa3f87a24d35a6e091005c993b", 0.499, 0.727),
            piece("PalaDiPesaro_c1.webp", "8faa267e411c7663daa82266f7645694305125d2d7891ff1641adb3c35d0c8cf", 0.781, 0.264),
            piece("PalaDiPesaro_c2.webp", "0fac89d68f27ee000e4f8315a6c3da10c88b20358730d8db4fe0c1d6d8ebb3db", 0.814, 0.474),
            piece("PalaDiPesaro_c3.webp", "e579ac110925e639579272e13d6d55289568e6db58c82c85b5379815caa7620e", 0.814, 0.705),
        ],
    },
    Painting {
        key: "harvesters",
        title: "Pieter Bruegel the Elder, The Harvesters (1565)",
        pieces: &[
            piece("PieterBruegel_a1.webp", "c0098f692b978ec09a0a47974be0edd219abe72aedf100c498ee755457d96100", 0.162, 0.163),
            piece("PieterBruegel_a2.webp", "7975a7e9c41b73c0791ae85dd8d665d16987d90dd2714aaf86f6f232da31748e", 0.137, 0.4),
            piece("PieterBruegel_a3.webp", "bcdde78e1860e100a7aa38b08ef6b3d7375180248f6a2e7b248c51f145504eb8", 0.162, 0.643),
            piece("PieterBruegel_a4.webp", "a35a632ea95632b31257a98355f24227197d22af441bb0505f7b13b2a99ebf45", 0.137, 0.854),
            piece("PieterBruegel_b1.webp", "14ac6d29d242ce598ba3273916a20ba411c9982f55efbe333dd21ff86b04c32c", 0.402, 0.138),
            piece("PieterBruegel_b2.webp", "104521b70d1a43ba1868f454400407703ba5775be4891a053916ffdb96b6b4b7", 0.377, 0.377),
            piece("PieterBruegel_b3.webp", "91f21334c83318b33a33412881f52c80810379d6fda4807890c9571b1ade57ca", 0.402, 0.643),
            piece("PieterBruegel_b4.webp", "ce0c070a7032f0fa79036c5beda564e7d982e06dc38c507c0b89f1c0099efe18", 0.353, 0.854),
            piece("PieterBruegel_c1.webp", "db8e05766bd584e6b5704c90909d0ec0c0d3ada4d23830eb0023bd447c5cf552", 0.621, 0.163),
            piece("PieterBruegel_c2.webp", "9f03cd588e44ac0ba72c92b6f29b4061be4f6ba1d2c91e5891c5f080d21a6849", 0.621, 0.4),
            piece("PieterBruegel_c3.webp", "a1799ca12d66a0ede888df6429a8a248129f3f989aa5e566e52ecd6a063b984b", 0.621, 0.643),
            piece("PieterBruegel_c4.webp", "aa71b92f261c9ed45219f07298a1b5390e20bc8d8944f4ef30911f002bf90012", 0.622, 0.854),
            piece("PieterBruegel_d1.webp", "f43fc7f9c0aad0faafc411742a8664e251265a263e8498bb6d360281a2066e50", 0.835, 0.138),
            piece("PieterBruegel_d2.webp", "2f5d8201fc9263b8c9897a0458db729ef8a03cc7fef7e9088c55b8835c87ec82", 0.835, 0.377),
            piece("PieterBruegel_d3.webp", "98c1bcea85f6bb3196e8e351d137260bfc25e1cdd6c10e567a16beecec297645", 0.835, 0.643),
            piece("PieterBruegel_d4.webp", "f24b546bf28b20e989c0f97a85c2773f9a9c4f038e4e8236597a5e6f3510a413", 0.859, 0.854),
        ],
    },
];

/// Every painting `--style painting:KEY` knows: the six, then the held-out fifteen.
pub fn all() -> impl Iterator<Item = &'static Painting> {
    PAINTINGS.iter().chain(HELD_OUT.iter())
}

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
    all().copied().find(|p| p.key == key).with_context(|| format!("no painting {key:?}; known: {}", all().map(|p| p.key).collect::<Vec<_>>().join(", ")))
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

/// Whether every piece of every painting (`all`) is installed in `dir` (presence only).
pub fn all_installed(dir: &Path) -> bool {
    all().all(|p| p.pieces.iter().all(|q| dir.join(q.file).is_file()))
}

/// The whole painting from its verified pieces: each piece drawn with its top-left corner at
/// `round(centre − size / 2)` on the board (how the puzzle lays a solved piece), then the
/// picture cropped to the rectangle whose every border row and column is at least 99%
/// covered (the board's outline is ragged by a pixel or two where tabs meet the edge).
/// Errors if more than `MAX_SEAM_HOLES` pixels inside that rectangle are still uncovered.
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
    let holes: Vec<(usize, usize)> = (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).filter(|&(x, y)| !covered[y * w + x]).collect();
    // A pixel or two where three pieces' anti-aliased edges meet (Hokusai's bridge has one)
    // takes the mean of its covered neighbours; more than that means the pieces changed.
    if holes.len() > MAX_SEAM_HOLES {
        bail!("{}: its {} pieces leave {} pixels uncovered; the package's pieces have changed", p.key, p.pieces.len(), holes.len());
    }
    for &(x, y) in &holes {
        let (mut sum, mut n) = ([0u32; 3], 0u32);
        for (nx, ny) in (y.saturating_sub(1)..(y + 2).min(h)).flat_map(|ny| (x.saturating_sub(1)..(x + 2).min(w)).map(move |nx| (nx, ny))) {
            let i = ny * w + nx;
            if covered[i] {
                (0..3).for_each(|c| sum[c] += rgb[i * 3 + c] as u32);
                n += 1;
            }
        }
        if n == 0 {
            bail!("{}: an uncovered pixel at ({x}, {y}) with no covered neighbour; the package's pieces have changed", p.key);
        }
        let i = y * w + x;
        (0..3).for_each(|c| rgb[i * 3 + c] = ((sum[c] + n / 2) / n) as u8);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The Rust table and `scripts/setup-styles.sh` name the same files with the same hashes
    /// (the script installs what this module verifies), and every key is taken once.
    #[test]
    fn the_setup_script_installs_exactly_these_pieces() {
        let script = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scripts/setup-styles.sh")).unwrap();
        let listed: std::collections::BTreeMap<&str, &str> = script
            .lines()
            .filter_map(|l| l.trim().strip_prefix('[')?.split_once("]="))
            .collect();
        let ours: std::collections::BTreeMap<&str, &str> = all().flat_map(|p| p.pieces.iter().map(|q| (q.file, q.sha256))).collect();
        assert_eq!(listed, ours);
        let mut keys: Vec<&str> = all().map(|p| p.key).collect();
        keys.sort();
        keys.dedup();
        assert_eq!(keys.len(), PAINTINGS.len() + HELD_OUT.len());
        assert!(by_key("harvesters").is_ok() && by_key("vangogh").is_ok());
        assert!(by_key("monet").unwrap_err().to_string().contains("pesaro"));
    }
}
