#!/usr/bin/env bash
# Fetch real paintings to use as styles in tests, benchmarks and `--style painting:KEY`, from
# Debian's gcompris-qt-data (GPL-3.0-or-later packaging of public-domain works from the
# WebMuseum): its `paintings` puzzle ships each painting as jigsaw pieces inside a Qt resource
# file (/usr/share/gcompris-qt/rcc/paintings.rcc). Every piece of the paintings below is
# taken out, verified by SHA-256 and put in the style directory the Rust side reads, which
# puts each painting back together (trainer/stylize/src/paintings.rs) as KEY.png:
#   $SNERF_STYLES, else ${XDG_CACHE_HOME:-$HOME/.cache}/snerf/styles
#   vangogh     gogh_auvert_{1..6}.webp                  Vincent van Gogh, Village Street in Auvers (1890)
#   renoir      renoir-moulin_de_la_galette-{1..6}.webp  Pierre-Auguste Renoir, Bal du moulin de la Galette (1876)
#   kandinsky   kandinky_{1..8}.webp                     Wassily Kandinsky, Composition VIII (1923)
#   greatwave   GreatWave_{a..d}{1..3}.webp              Katsushika Hokusai, The Great Wave off Kanagawa (1823-1829)
#   cassatt     cassat_summertime_{1..6}.webp            Mary Cassatt, Summertime (1894)
#   bazille     bazille_rampart_{1..6}.webp              Frederic Bazille, The Ramparts at Aigues-Mortes (1867)
# and fifteen held-out works, no default was chosen on (keys durer, librarian, spring, ejiri,
# ryogoku, oiran, poppies, fan, kazusa, prawns, inokashira, pieta, monalisa, pesaro,
# harvesters; titles in paintings.rs HELD_OUT).
# Idempotent: does nothing when the files are already there with the right hashes. Uses the
# installed package when present, else `apt-get download` (no root needed) into a temporary
# directory. Exits non-zero only when the paintings cannot be obtained.
set -euo pipefail

STYLES_DIR="${SNERF_STYLES:-${XDG_CACHE_HOME:-$HOME/.cache}/snerf/styles}"
RCC_IN_PACKAGE=usr/share/gcompris-qt/rcc/paintings.rcc
RCC_SHA256=1276d4f9c26f94ec130833c03bea5185f61b4f986df6981182cdb1be69e9db98
# Same constants as trainer/stylize/src/paintings.rs.
declare -A SHA256=(
  [gogh_auvert_1.webp]=81f84ce20f31486197f459635ddeef042344c694af6fa130418a36b1d45a6904
  [gogh_auvert_2.webp]=c4518c2389a6c572ad1ea623479e7a5030f3aa59dedc9c4cac73d55cda96c86c
  [gogh_auvert_3.webp]=1aefb708e7c36a0e4c7c718e8cd2fd37d8321d7a4018d916f149314e4d4bfb98
  [gogh_auvert_4.webp]=8cdc157e260d5d1864198c72951275c405b6f74568c836f285781caba0895f3c
  [gogh_auvert_5.webp]=4bcb1e64c44022b79a56aba86643fdca26bad5d2a908c56400240fe9f08f1142
  [gogh_auvert_6.webp]=b8ab1e32b422995ced0bce842a126da84a9db9d3eaba003934eee3c7ed915204
  [renoir-moulin_de_la_galette-1.webp]=78880d194c3be92da64d89bca581e09c699303f7848c84f653f6cca0a14e2422
  [renoir-moulin_de_la_galette-2.webp]=297bdebac908b464b7b76a3555cbfa2192816bc660859dadc6041caae5f55617
  [renoir-moulin_de_la_galette-3.webp]=185c721373176d28f518a5625894def2389bd29b0be65ddef802a48e34898c57
  [renoir-moulin_de_la_galette-4.webp]=182d1f65643f33d6583b9a3b3a6831af42dc0f0e11c65414e5656e13e619dbf7
  [renoir-moulin_de_la_galette-5.webp]=593aaecdb2bc1cfbd6524348538abdd82242f4d70aaeb20a3b932d494e2d9c1f
  [renoir-moulin_de_la_galette-6.webp]=e9358ce944f2f77fc618d6c3d357e3e3aec4dc7626bff40be1b994ad2bf640a0
  [kandinky_1.webp]=67bcd29206ed353a21f6ea5526d1b4f77f4647f6d7e1d8f3f4bef6c2298b65c5
  [kandinky_2.webp]=0315468377f7f36584bb0e46e1e201a525aa7c1bc9d1685af7990248c68a7255
  [kandinky_3.webp]=f9518aa6512a0e454a22e850f77d43ed7509e8a098fb5dad5ad22c10fd32e51b
  [kandinky_4.webp]=92e3ebbaa42df5af6129dcb749a0f6cfa9749a469410077b6d8d00ac2b886db9
  [kandinky_5.webp]=9fab6cfbfb69cb6f4089ba1bf81cf40e32b4b61125ca1ef9ae50c1461362377f
  [kandinky_6.webp]=4d96b7997185047abc6ca0c77d9c742c9b9aea6514e14e5cb7865d4b723aff54
  [kandinky_7.webp]=b7567aacb05ec786f11d4a0da407b95d4a1b38675b2462646cd515e865cce500
  [kandinky_8.webp]=0c7b9d5d01972843c9a4049007bb8b22c8ab352f656782d5fd7dd4dfb9cea297
  [GreatWave_a1.webp]=0e83968ebf461cba0bc90021e78ac3934ed41181a1c2f3d587350c41f5bdc7e1
  [GreatWave_a2.webp]=35110e1c3ed5ea6aef169dacf16001972dea04300484bb503785a61b71e41bf9
  [GreatWave_a3.webp]=897aeb56b0e2c527b02c40d5eeda7c101eebeb3e432770bf89861d9aa0e6414d
  [GreatWave_b1.webp]=28b72a3a9eb6e798eecfda187705e1e56955a5e19b18006a0b33aed8ca48aff3
  [GreatWave_b2.webp]=342fea36ea63073282803f7e36fe770b5d8e2f1906c512e19c24af9e68426915
  [GreatWave_b3.webp]=6b6837959b9ab7e89a689be1ebdcea8b53edb52e5b4f974953b5b7dc50b13b2e
  [GreatWave_c1.webp]=67422ca616ef0395aac3b3fa5acba56d4aa6a0e0e1efee40f33a75177966b723
  [GreatWave_c2.webp]=6679166308a66aa4ab4c0d3633838074a0e322ae40486b2a16e5cfa347922eff
  [GreatWave_c3.webp]=af0f79b1302665cd5e6c0a83de694409c26a6d132a09bee57b4e91f7b3ac34b6
  [GreatWave_d1.webp]=8ce5241159d5e659e14f223caefa369ce625696cc0e35a66bc0052f124cd0fcb
  [GreatWave_d2.webp]=5d457790ea88e216813ec4405086ebf8883c657c7061148edfe565458a04b1c4
  [GreatWave_d3.webp]=2491c11e9208b6b2161acd95cb9eb646f88184f48ae6bae88119221406141a82
  [cassat_summertime_1.webp]=12250ef3b55af74fc45b2c3597d9bf4d02675650abdbc8bf0885635704065e16
  [cassat_summertime_2.webp]=d17de55174fa12b04db04b0bfed25d9176ce912e643b1fe1dce31532eec7eb7f
  [cassat_summertime_3.webp]=13f4baa81dc32bec7494b524d551736acbaa99e7f6d9ab233ba6f90dc71814f6
  [cassat_summertime_4.webp]=48ada16b2b17e20e74875cb429374c2af58d0c43c0b881d9f941c91e15e96478
  [cassat_summertime_5.webp]=3d3cc54575c97fc4fc451ea5e65aa40ecb7c762ed2b0632fd4d44dc42ad9f62f
  [cassat_summertime_6.webp]=a9eb351191253246cd20c5c619e9f699747a547f881bf17f3341dca4cacb8d76
  [bazille_rampart_1.webp]=6a16546cd624d715e7c9f29133f0667bb4e07a035ebaafb5c392f6811c30cd52
  [bazille_rampart_2.webp]=365fd7e758887e5aa6390c067e57773e0e5aaff6038436dcb86c1d40c08e25bb
  [bazille_rampart_3.webp]=1c0393db1da6c10eabac5b1935068e64836a6d9724b010daa51cbdbde02b32b2
  [bazille_rampart_4.webp]=3508ea1d28bcbc3e34ef11013e73c587c81608e74649b5efd4b2f3d20da1dc0e
  [bazille_rampart_5.webp]=80bf7e3bd9552d8f1df5b66e5f2936856a9bc9d8f96d0d530f7b4e2dc2869577
  [bazille_rampart_6.webp]=7f0d19fc2fa3260ed976ee209bd5a1a5d3fe373e936e5d2451d864682a9d5f4a
  # The fifteen held-out works (paintings.rs HELD_OUT): the package's boards 2-6 and 8-17.
  [AlbrechtDurer_a1.webp]=a292cce2c1682166222864b7ee8ec4bb31e1074ae679505b325276ea06870698
  [AlbrechtDurer_a2.webp]=e007e72459059688ee2921dfee7a21a874ad96fb20ab6daf58532ac2b7b4291a
  [AlbrechtDurer_a3.webp]=60963024b7cd0a0ae9bcaed5dad657d1e17ea0014cfd157e1a933a077110827d
  [AlbrechtDurer_a4.webp]=261e5a9fe93613bfbe16d58a5eb8d417c69514afbab3210c6f0813eb666c84a3
  [AlbrechtDurer_b1.webp]=7038e54836a10269cdb3d19d328bced8c63e1d1aa1495ef7f5f0e5c7b166eff8
  [AlbrechtDurer_b2.webp]=30461725e628e1adc4fa72ea384f2465f6fe53d64401ab4146b83e93eca07d59
  [AlbrechtDurer_b3.webp]=f118cc75e951a076b11920edab9f8976bd8f5e2496c179bbfd7cb5dffe608898
  [AlbrechtDurer_b4.webp]=bc6ab53107a64f33f630a5f5dcee2c1d886b4f258a099958c41a1d533c81336a
  [AlbrechtDurer_c1.webp]=1d2aebe5c52769a2810372f0248b76770c1306ac88f53044e294eff9d9181248
  [AlbrechtDurer_c2.webp]=070a33a9a22da13d7a16158606c355d31886f0dd5d54f33790b0133f2d36b72b
  [AlbrechtDurer_c3.webp]=ecc045d92cee52bdbf308dc5fa498a6c5948d80b56c43297cb2f99ee5dd280b8
  [AlbrechtDurer_c4.webp]=da868de1f7a7555d6c6d84f920c91862e0ef2297b3a5ad411247019c39b93348
  [AlbrechtDurer_d1.webp]=d32da7662a6eb9993fa1c30fcc90e6e6b87110fd919baee499fc7ffb2de8e303
  [AlbrechtDurer_d2.webp]=5b6642166d8ad05fe74811c3638184816df77a1e871e201fc98dd76f67e12ff9
  [AlbrechtDurer_d3.webp]=8d69022ed5b733c2ed34d4aaec851e8b6b3000ba6e73593df2d6d669745f90cc
  [AlbrechtDurer_d4.webp]=bf2e288c9f788b0d1d030219555935e569d8d9ee046528c6a0ee8c1dd3d5d75e
  [Arcimboldo_Librarian_a1.webp]=8f16256d00a6aa72fac43eb9314d6d3939c86da9c5725d5324918984f49c8e03
  [Arcimboldo_Librarian_a2.webp]=5babf15b69e6de78cfe550909ca1b2f3c84da3179c42bb1d47feea6d48d3ea02
  [Arcimboldo_Librarian_a3.webp]=c8d854f65cd46de7ed4d388bb90400fe7f0d3d4648474f06dc746caf7f056a0f
  [Arcimboldo_Librarian_b1.webp]=3677e336ee84b61d76bb17e7b58c37207df0d2d3db8eccda002a1c32bb2129e2
  [Arcimboldo_Librarian_b2.webp]=86b561e2bd2c307b8763cc8779482ba8a7bb26b81dd697134d2b3676e33dc5fd
  [Arcimboldo_Librarian_b3.webp]=93f1b57af348d15fa777c31d698fb95c31f665689333e6e1aea73d69cbd00aec
  [Arcimboldo_Librarian_c1.webp]=d8038e0e9788114b71898bf74be85c8c942188f9b94fbf78c711d62889eedbac
  [Arcimboldo_Librarian_c2.webp]=a96e265f96a59c800ce1cbc09694931bbd85c0089a332168bb6cbddcddc3ca76
  [Arcimboldo_Librarian_c3.webp]=ad960a4bc066f536d153913bcec7cafc7bbef13af3796e81642d43a3810b1900
  [Arcimboldo_Spring_a1.webp]=37816ac81d9d517d04fb88fc728b44d2b100bb5f8406d044ac812708ea29ce53
  [Arcimboldo_Spring_a2.webp]=59474f5f0d8ad946a307f9520b8ea4c31823e9f88f1937cf410fbb667a78f5a2
  [Arcimboldo_Spring_a3.webp]=c3f20dc47e9b20108bf892c5173f01668538f21ed846874c635f2496b3b1e956
  [Arcimboldo_Spring_b1.webp]=a80854a1d38839837ee56b594725c3ebc6a3d2ac8e0259aefdcd29d4ce45644c
  [Arcimboldo_Spring_b2.webp]=752dd5271e3d6600064a507f555764a5b432794e2426be7bac39e366a198c250
  [Arcimboldo_Spring_b3.webp]=d36caa189e3e7223ac8de440b6c47a5a703d17072499b0da29a4104db21224bd
  [EjiriSuruga_a1.webp]=6724ed375ba4023e3b35f6a3bd072242dd97199e2363b1b6779c357378e7e0f5
  [EjiriSuruga_a2.webp]=6962d5c9069baf4ea5ab2d9c4d525c9ae3ed62c78bbc1d76427d884590fbeff7
  [EjiriSuruga_a3.webp]=a7f838dac1d7193c2cce3b481554f110140141da966b0c66c3199f917254ec78
  [EjiriSuruga_b1.webp]=313c87d521494ef6d80464bb8f783c6b4eab7eec3ddf7b42662011c2ee6ca17c
  [EjiriSuruga_b2.webp]=9eb22f44d6270400d4e995ba82e10acfee7ec504a406bc5f8453578f4b49bd6f
  [EjiriSuruga_b3.webp]=4be5a6f974b6e88212bb523a48b768d8710bd716749c92a00f85a079382bd83c
  [EjiriSuruga_c1.webp]=a2a52da406ccc97a6efc36a411e48711709decf11814c78f2b36cf8fd623f68e
  [EjiriSuruga_c2.webp]=42ae57a5766d4aff7a1c2ae7a61690a5cd9307edddd96d1fb724ff398871be43
  [EjiriSuruga_c3.webp]=b7f075c282f76a62398e491ca44c9e28121823641217dd6137b7417e7365dd69
  [EjiriSuruga_d1.webp]=4263ff3c20a012301319106bd54c9de3b76cd25caa82a134c4bd9fabea7f25ab
  [EjiriSuruga_d2.webp]=373334f1546d99b9218e663afb8a6b00d30319a696894596f3be5865c9672ef2
  [EjiriSuruga_d3.webp]=935764a4b0acd0a00c35f15dea04f9ee324dcdd87f71f5c0e08619f1adf57694
  [HokusaiBridge_a1.webp]=ff553c4faaca60b322c970de9048931fcd2be71e144d58351c8d5303150d4931
  [HokusaiBridge_a2.webp]=d9cb7b5a9bd7681234b8c57d9bbaf9abff88075c36b222ba00b4e1e1cfe65e97
  [HokusaiBridge_a3.webp]=1eb2ac8ccc2ef4ce41a7b6b81ae730d7f62ba4cbf600f70fa425c8724b29db46
  [HokusaiBridge_a4.webp]=a3cb33e52382a75dc914c7386dbb304187b4929d920627c52cc1d4e8ffe975d3
  [HokusaiBridge_b1.webp]=7b2195ec825490bd8166024166ce759566e94b8d2b81bf42e6c6e7ee8825d4c7
  [HokusaiBridge_b2.webp]=6b645ec543e0d44a6908d65cb50460f9095dce6acde8f8d76f010723de3e9395
  [HokusaiBridge_b3.webp]=7dda1c169096173477fae465a8ebe7ef2e11fd2374e359400f802626d8a07265
  [HokusaiBridge_b4.webp]=78ff680b3a26989a73c793b63c3a3e80705908815b577a993d4e2ca898e5725c
  [HokusaiBridge_c1.webp]=0a3ff017c67357e4288a66a942808a0e7d62abe8380c35879094c19117e0bae0
  [HokusaiBridge_c2.webp]=0e73560a33649ca0639197aa4d94aa37071fc88a506e4ab153bdcd1828d883bc
  [HokusaiBridge_c3.webp]=f622cf4b3b074d366f141cf545dd98050ab38813311d1b19ab93a7fe63c8c19b
  [HokusaiBridge_c4.webp]=f3a0ef87a1c611a5516fcd7571795b6c90ddc8c94ef4b112a968ee2ff847b33d
  [HokusaiBridge_d1.webp]=977cd3b8efe03e5321d935d2b055b947ce4b614cef99f64fc0db2e35a45a60dd
  [HokusaiBridge_d2.webp]=f7d4f54dd113b020f4704ac8db9a287739184dc7ab91cd16cb17bb9545c54bf0
  [HokusaiBridge_d3.webp]=6909eb7879b0784e0d7afc6e293d850e39dcebe9315981a1ca9979d3eed9e148
  [HokusaiBridge_d4.webp]=1687414c0a224ec7a5451d8fb453853c578c93849cf2c0e3669f3ce1b02422ce
  [HokusaiBridge_e1.webp]=02c8ec3848e046ce02f255152d4e319ad044ebbaafef7f5add8dd564718e4f8a
  [HokusaiBridge_e2.webp]=26d60496b23a78c7691dcbeb070796f1f8a6ad15feae293e31c4ea9db1d13bca
  [HokusaiBridge_e3.webp]=4042c89b677f26b6e796dffbef90d70f63bf9189a46f3c6d255f9f853d88e601
  [HokusaiBridge_e4.webp]=35c2888093c5b214a59f37eceae9e1444bd05c8825e8eac0ae28ea87b75fadb4
  [HokusaiOiranKamuro_a1.webp]=d029151c03f2dca9d79fc8c041a6fae488569ae73c3086ca01a7039766687494
  [HokusaiOiranKamuro_a2.webp]=f599ebd4f80f62d98424b2574f97d909f60f94ab7272652c95951712fa86980c
  [HokusaiOiranKamuro_a3.webp]=3e939f83be171528129ad518f74c3e19e128b1ad4178de418e72f61d914a9081
  [HokusaiOiranKamuro_b1.webp]=846f1d8a287cfa00f323d5732a4b4110ce70b925721804668641231dbb73e9f6
  [HokusaiOiranKamuro_b2.webp]=07ad84266dc3a21181143728046bff6e09207a2cd46220342e11a1388e924e2d
  [HokusaiOiranKamuro_b3.webp]=c05d52c7194a997f8c77e5273f61432ae549ca6bf113c358b7a7c9cb7fbc2079
  [HokusaiPoppies_a1.webp]=4429080ec009e12177fe8bbc70188ca7fce66342d139519b1d711e787488d776
  [HokusaiPoppies_a2.webp]=838bd3a3645b7ad6805188834e934f83b540c99df4a1cee4075e037607b520f4
  [HokusaiPoppies_a3.webp]=7d1f6fd3263b0145b4bdf1b39993cbe10c8cd0aa55ca408f6b8c30a57da4b24d
  [HokusaiPoppies_a4.webp]=25b9e000e63b2aea42dc55702569c23daf8127be2e6b799196354df4f02df5e9
  [HokusaiPoppies_a5.webp]=cbb34e88c7d9a1ffd6ca9d060f19be83747b7f83ee2ac8b4865f75350b9dc85f
  [HokusaiPoppies_b1.webp]=460c026dced7c7917f0df7ce9abb77a7829c97b82e3655acf84a8b63a80c6edb
  [HokusaiPoppies_b2.webp]=be15848d5619e5301ba85a48ea2e187eee890ba02b8663fda3c947d2aec1987f
  [HokusaiPoppies_b3.webp]=db86e75e1f1fd249bac93c88da90080c233ffd49474746213c38c3ca69cac118
  [HokusaiPoppies_b4.webp]=f9431bf57205090c99eb85c533aa2f036213f14538ee5a1884d843da1265ce9d
  [HokusaiPoppies_b5.webp]=d43420d2c2394d2b7c9ec3584f22997bad4e16d8407e44264659fbf852629ceb
  [HokusaiPoppies_c1.webp]=9ff12143f4e5fcee6f9c9edc9253b413de05d8cbdcab417a5cac8865b8b083c6
  [HokusaiPoppies_c2.webp]=60d00670f6ca740cdced726f9a10f659ae829277583ae615548e187b14ac6f14
  [HokusaiPoppies_c3.webp]=f1873868fba6e3232bab5193ee6594ce168817240a156086ac0236375282e2d3
  [HokusaiPoppies_c4.webp]=94fb8ef6dc493af08e00de11d82808472b384df3761fe6cde68a9b20675b2b8f
  [HokusaiPoppies_c5.webp]=b7aa660c193c286a02481a0f9cfaca509d81a9ef10871c7a911ce960895dac5b
  [HokusaiPoppies_d1.webp]=3562fee279e1287e1004371f4c612a8ff99717419ce6bed94202dd8ee450ff71
  [HokusaiPoppies_d2.webp]=4a2a05c61c47ad793664bfea734a9623456560d35d297638c228f9dcbd89161c
  [HokusaiPoppies_d3.webp]=2d45583c32ed518441d2e57a656b74688f7f73e238036e3b1edd6a460e398423
  [HokusaiPoppies_d4.webp]=86e1a6fe6cd4a60c00a207e3a1693227d0442f2c7bbd340e48636489379b00ce
  [HokusaiPoppies_d5.webp]=adfc8189b45167b0b0761ff1034f4fd62db9bdb3cc172add3190da0bf1bdd425
  [HokusaiPoppies_e1.webp]=c4e8a35bac187c29b4696d26c3d5d1c3f1f4a6aba5be14e29c7af789ad3eeeba
  [HokusaiPoppies_e2.webp]=005d8a14b7974a4b84d7a8a67b5d9a7be2858cfe37a37e22bbd40486948f1363
  [HokusaiPoppies_e3.webp]=be19874c7b5fef8fbcebd424216706e7a73355d1a3f5ff71d04caaf78b4b1ec2
  [HokusaiPoppies_e4.webp]=35840c5f1dfe722ef3e70cc4bbe1ca8529e52e91451538a6667c99d2a7e9eaf5
  [HokusaiPoppies_e5.webp]=492461ac3274c661f1c120b210483e112ca0691c9fa32b1e6004a3429b6a1a23
  [HokusaiWomanHoldingFan_a1.webp]=a04cc510c0168864cbed71a5af3c27ccae560f221b39a08dfa6fc32697e70b7c
  [HokusaiWomanHoldingFan_a2.webp]=7e7e7384e1da5e155c24c5f2c6b9cee698ea2efedbea73c9472b9273b48811b5
  [HokusaiWomanHoldingFan_a3.webp]=2c23573129e588d66adbdab29f10ea22c9dcf3d5df327797d745e328536f0cc1
  [HokusaiWomanHoldingFan_b1.webp]=b75413b0d1912bb17a39eaf11f6922e1654c0ce762e24b1968d3d364f9c78ed7
  [HokusaiWomanHoldingFan_b2.webp]=9e286bdf6521fe2763bda79c7474fd467598777565b667bdf82021400cbb5fd5
  [HokusaiWomanHoldingFan_b3.webp]=e6a9b15a57fcd475f0032044e2fdccc932482bd626796d249509699d14bb8bb9
  [HokusaiWomanHoldingFan_c1.webp]=74271cc15417e3c63eec40ace6deb929b27ab27e4c0b4925a0b9afb7b3e2998e
  [HokusaiWomanHoldingFan_c2.webp]=fbdb67f4e6c6363afed5662b370c35d88f75806676a0f1ee15c48e5837aa7167
  [HokusaiWomanHoldingFan_c3.webp]=6920d6eed15a4a8af0096584e3da0f73fea027b0202d5e9beb7970bdb1dc2fc1
  [KazusaSeaRoute_a1.webp]=729156dfa1854f3aa02d02f7fd75310ece0c512898bf9f291524a08927dfcaea
  [KazusaSeaRoute_a2.webp]=d0ea523d71c3d7c8a36dfa830c843dfb6954a890b125d4ef26a93ded5abe08fb
  [KazusaSeaRoute_a3.webp]=ad52e2bce20de6a3e91b9164312779a6d38a9f640f5f33f9e9158c6c08d207a6
  [KazusaSeaRoute_a4.webp]=4a10a7ea07e2cd510be6788e6edc832c1df58c4581a0c2e6a9c6cd30f748ac8f
  [KazusaSeaRoute_a5.webp]=d829b7d94593a9a031299d54f8bca1f7bec2f94d373981dbde2d1af7131ba07b
  [KazusaSeaRoute_b1.webp]=e6a8640ff9a97c10bd40ec8e1c37de28c697b102894fa5ca5baa5916489eaaa6
  [KazusaSeaRoute_b2.webp]=54fbd6f4d994ec7de586ddc471db24731d7db81a8534188179a28c12b35f1538
  [KazusaSeaRoute_b3.webp]=d8f618c9a46e0af7bf9dbe526e1f948a148c0153cedb45e7020cb8167d6f3416
  [KazusaSeaRoute_b4.webp]=aaa2b77d254854bb0d800b0f796611a435a5c0ea70ab404af089a314625a76bc
  [KazusaSeaRoute_b5.webp]=92f1f2d46a66c3b8c44925776b5c3fa4ccb998dbafb772a3cf2b1d8776c331d7
  [KazusaSeaRoute_c1.webp]=8929cfbc82afa13c0587c655e23ef98ce9ba00cc09af3ade01bb70db8d522d0a
  [KazusaSeaRoute_c2.webp]=5a7136603b37dc92ba67ddb12e67bb4195534662f77c33a97ee79b3b0fe6513a
  [KazusaSeaRoute_c3.webp]=997a8bf365d3e214200e4d2939f6e5545c12afb1e975ffc259559d893be713c1
  [KazusaSeaRoute_c4.webp]=5027a99e7365e030e75ced0eabcfc486bf0bc07b22fd9c64b0ea172a7599f009
  [KazusaSeaRoute_c5.webp]=b2a6d7711eb0b045ecc48b12cf170f3d61be02658172fe6ba391cdeb78cc534f
  [KazusaSeaRoute_d1.webp]=549481f44aab521512771d7f8014297c88e04f352ffefe51808bfb4571c57ea3
  [KazusaSeaRoute_d2.webp]=dfb42e5ea7d4f373dc7a8cc1ece9ca178cdec9037c613bac260fd9046a5c3875
  [KazusaSeaRoute_d3.webp]=1a46b08c01d1d7284596a111b714c1d56497e8e9513da9757b167d77e5d3751c
  [KazusaSeaRoute_d4.webp]=2194cdcfce80e79f180d1c5bf93a7fc2decb918c1e99c9bb8139047b58981e91
  [KazusaSeaRoute_d5.webp]=b68d8e2223e0cff32fa26b4191e799870be6befa054ab5d5b3ebbe7529be6188
  [KazusaSeaRoute_e1.webp]=70f16be009e4d60dcbda6fdc69962c8a8207ecad6af76a70154e860f76ac2e0b
  [KazusaSeaRoute_e2.webp]=095c66fe5f60dd3d7aa5a329e203102558e3829a4310b0635cc91518dfff21f8
  [KazusaSeaRoute_e3.webp]=d8a530146d05222872efe2ad4d84d202436933507fac7972f5a23801a9b36df9
  [KazusaSeaRoute_e4.webp]=001cef5bb080882b0e2b0a87c40ca5bb3d491795519da4b38804edf74f0b5a48
  [KazusaSeaRoute_e5.webp]=7104aba7395158a6f1e0c8866092c910f3d544e918667352a01c617e1aa64498
  [HiroshigeHorsePrawns_a1.webp]=d3e4fed4b834b8da745d5e60f29e498e7db50729d3032da79d575fa75fd36c12
  [HiroshigeHorsePrawns_a2.webp]=c0db7637115ae575485d59a27e691e285d256dd7b5c0267173d2e47e3d90af12
  [HiroshigeHorsePrawns_a3.webp]=f13541b652185026bd82b582630e75939cfafcdc2d97546262f315e66879971e
  [HiroshigeHorsePrawns_a4.webp]=720bf2681396202048a21b12f113d69cceb884f879e515db16d60da2151ded3a
  [HiroshigeHorsePrawns_b1.webp]=1d5f568ec9a1d9d3715194bbd10ea5d30a5cb0a24e87a4812e68f5063d2a9cf2
  [HiroshigeHorsePrawns_b2.webp]=f46dc06baf61f3380249f1bf0d421d4d1f04df0d733e1841e6e54b848b3f6fa0
  [HiroshigeHorsePrawns_b3.webp]=68cd13342da1a172af4bf05aa8556e3100ba169ef66d74ee2b1d84def602a5f9
  [HiroshigeHorsePrawns_b4.webp]=3d6836e50e0ba1d67a83a9a1df9cfb6e1dd613d2170fc6311386ef8fa85f1258
  [HiroshigeHorsePrawns_c1.webp]=879fbd0001d1a7bc8c8a059c6eaeb151fcda1bfcb2f71c33b5535d6ee5dae171
  [HiroshigeHorsePrawns_c2.webp]=443c7f3d4a3eda6c4fc62f96ab668b1f8f55d6a5bedf24c2452391b133c6906a
  [HiroshigeHorsePrawns_c3.webp]=22f7e5e08c501edf3ccb30c234243cb876b8a7a40e1da070828b2d46bd9f567e
  [HiroshigeHorsePrawns_c4.webp]=7ede434ec087710a641f07c32159c0a3e6da642e2001cedb1c55b80fe6f24e86
  [HiroshigeHorsePrawns_d1.webp]=32d63c7b0240014a8b967c091f982c89540d1ab6988ebce2894fbcaa138ab867
  [HiroshigeHorsePrawns_d2.webp]=17c05791c8084c4a41813dcb2f8a9b3b2cf266dd4fedeee5436597fbdf0e6886
  [HiroshigeHorsePrawns_d3.webp]=93dbeaab7ac3a9d6bf166b61ff96646b9e36c1e36817309e0a96714fa1ec73d8
  [HiroshigeHorsePrawns_d4.webp]=7a50fec6cb7e7a7b7ad31d9c9c0960f186b44518b962924e224bd16d3bc30a7b
  [HiroshigeInokashiraSnow_a1.webp]=8463228c567235064268b1b81d4652183e87e18836d7300c736a2d2a040c5c11
  [HiroshigeInokashiraSnow_a2.webp]=805c567a58c7339fc845383bec18b74b6d8e6d8eae0d29bdf87caa6b7bfb52d2
  [HiroshigeInokashiraSnow_a3.webp]=701f3f2437126a34188532470648362f862fce22c9a467ba4eaa221898fd1fee
  [HiroshigeInokashiraSnow_a4.webp]=fe06c9f2f645ad77106cd558da61cf70f97589970381ff8e0606a4f3e2a0759e
  [HiroshigeInokashiraSnow_b1.webp]=78a178688f18f793215c5e52f38f4e9405ba0bf81a4e54dcbf5cbba180ef0e2c
  [HiroshigeInokashiraSnow_b2.webp]=cb9b7230efae1566d0de2067b14b6ebd294890f43a95267ef6814e893e3f6424
  [HiroshigeInokashiraSnow_b3.webp]=d285b08d007b79e795a9a2179429ab96dc99788483a08d988c2421b037ccf29e
  [HiroshigeInokashiraSnow_b4.webp]=3cf0972da5053035b1324764caaf39619a9583862eab0d44b64e03afccb74347
  [HiroshigeInokashiraSnow_c1.webp]=570c68c96a9d8229a78aae2914f51a39544ca08e36327f2e18cbb642b5b35752
  [HiroshigeInokashiraSnow_c2.webp]=755a1e95674b8170d5fc8a3494401e2d503588980098b6df08cd75a0e0a08630
  [HiroshigeInokashiraSnow_c3.webp]=0cc29f0af5c0d22f78a82431483716b45ef31f4a1e527db60bdd89a0475d9657
  [HiroshigeInokashiraSnow_c4.webp]=ccf745a5473cf37d457facaf0118caeefdde9fddfffa87fba7faa612a9110388
  [HiroshigeInokashiraSnow_d1.webp]=908978cf201fad42ecf164e9e812bc553911c23a30fca9f09bf58b167b77cb2c
  [HiroshigeInokashiraSnow_d2.webp]=b7180f8d1289c9ccff17e7cce71257e0ec265b9caead15972600c2a0b3e27e15
  [HiroshigeInokashiraSnow_d3.webp]=517fefdb197fcc056ced16bc5edaa7efa14188360413e71e55a332eec8d0e870
  [HiroshigeInokashiraSnow_d4.webp]=1f4b97256d480585eee37b3c4346354839154435a46ada507d89b0fcb7d3d976
  [Michelangelo_Pieta_a1.webp]=ce2723024814aca9fcbfcb7bb88d85c19484165ebf697ee05cf12d6b036c7168
  [Michelangelo_Pieta_a2.webp]=387740a87d2874c24d9124cd996c9cf96cdf727c76c4d59dc153c246a5510764
  [Michelangelo_Pieta_a3.webp]=f514549b84a29dcd5f2848709d5777a460e252fed7cca3b40cae54bc9cc67d7d
  [Michelangelo_Pieta_a4.webp]=a0b380752c44ff9e16730882e33a2c976ac4bbb7ef6c18c3e8e33884b609b6a1
  [Michelangelo_Pieta_b1.webp]=3dc80e59239e3dad90e3239e104cb8e0d55bae14101521b95f7f63d97320d3cb
  [Michelangelo_Pieta_b2.webp]=de6acb5e9dca5705a3d6d7a23b5442f170a7a1c237cf275177ed7115495cc2e8
  [Michelangelo_Pieta_b3.webp]=085be9e34c4c827aa2252629231c510b5901e5f3a64aab4d31abd5f7c35a8819
  [Michelangelo_Pieta_b4.webp]=34f715a0cf192d2401ffd685c1f5f97fbd6bfb699c5ffac94c7b4af640aa0754
  [Michelangelo_Pieta_c1.webp]=2eda236b512c8cbe51c50d1176f8975130065640f470aa3e37a7fa6ff131c3b2
  [Michelangelo_Pieta_c2.webp]=98b253d1dc639bee8ce459cde3b91ef4fc8d92c7a3790ccf27b3a8d313846f90
  [Michelangelo_Pieta_c3.webp]=94262739463e5e1f41b7d34ddde18088aad4406e8137049909cf84d8afe96cb8
  [Michelangelo_Pieta_c4.webp]=a2d54ee1764972d9d8d45ca7a56e4802321fe8cc42c96a34642194657a721288
  [MonaLisa_a1.webp]=0d69e4bef885e1d6583160414b3e0bdb9b46e203f6dc1ffe7066075cc3bfec6d
  [MonaLisa_a2.webp]=c985203d84469032032586bb9dffed326bc45122afd3e5ad258f7e92263c3d6c
  [MonaLisa_a3.webp]=c982051cf60b1fd92d762bf0453ea6d86153496ffd33f8c9c97f1b45eb512934
  [MonaLisa_b1.webp]=9d3b46a53a2abce842660564e4826f2af3b3335df07572cdc81aee6f282b7046
  [MonaLisa_b2.webp]=331eca239b3eeb1b1514a234630dee63baeb722fd7419cdf2c42ac70e75e8115
  [MonaLisa_b3.webp]=b655a1707b8c25f53173bfe0cd6318217e2877d2fb7a90a630362b85dffc8295
  [MonaLisa_c1.webp]=83f4abc55c4c06b00223eb2fc616731e09e134e5621cac1fad5922513c587be9
  [MonaLisa_c2.webp]=3e09d643604d2da186c5b484861dcd7c88d12a114b3b45d57aad80d7db746713
  [MonaLisa_c3.webp]=ff1a07ecc7e560b4ecb78881754f3aa7520914ebeb9293b88566d77282173f84
  [MonaLisa_d1.webp]=0d5961d6fd19bd72cd65f67033ad13b6d18cb90768d46d42641ee3194e811cb7
  [MonaLisa_d2.webp]=6d0add0b76699742def0979aa00910709fed2254daf308a18095b241029fe744
  [MonaLisa_d3.webp]=97456266057a96e3775e902ee5625a979b19f75998f612bfb596fcc466222f4d
  [PalaDiPesaro_a1.webp]=b74c706b3f043958c50a69edc7b86679b2c63c4714ded93e1dd314820ecc9f71
  [PalaDiPesaro_a2.webp]=09722459f509290510d1e34a81dd07792c81ace1507d8b815f8d67d85cf2670c
  [PalaDiPesaro_a3.webp]=b09b5cf104142f528a134a6eb928a867ec9cfd4f9a2751de9dc10b0e0ef4793d
  [PalaDiPesaro_b1.webp]=94820978adbc91e955bce9a64e8ccdccde27f97fb0524aa51b27b0ff85ea66d5
  [PalaDiPesaro_b2.webp]=3fab215ad03c9e8237bb10053f3dd1102a26bf21fa3bc2ec43fbd2736f021181
  [PalaDiPesaro_b3.webp]=66471a5d68b3cae0f1c5863acecf27f84c2137fa3f87a24d35a6e091005c993b
  [PalaDiPesaro_c1.webp]=8faa267e411c7663daa82266f7645694305125d2d7891ff1641adb3c35d0c8cf
  [PalaDiPesaro_c2.webp]=0fac89d68f27ee000e4f8315a6c3da10c88b20358730d8db4fe0c1d6d8ebb3db
  [PalaDiPesaro_c3.webp]=e579ac110925e639579272e13d6d55289568e6db58c82c85b5379815caa7620e
  [PieterBruegel_a1.webp]=c0098f692b978ec09a0a47974be0edd219abe72aedf100c498ee755457d96100
  [PieterBruegel_a2.webp]=7975a7e9c41b73c0791ae85dd8d665d16987d90dd2714aaf86f6f232da31748e
  [PieterBruegel_a3.webp]=bcdde78e1860e100a7aa38b08ef6b3d7375180248f6a2e7b248c51f145504eb8
  [PieterBruegel_a4.webp]=a35a632ea95632b31257a98355f24227197d22af441bb0505f7b13b2a99ebf45
  [PieterBruegel_b1.webp]=14ac6d29d242ce598ba3273916a20ba411c9982f55efbe333dd21ff86b04c32c
  [PieterBruegel_b2.webp]=104521b70d1a43ba1868f454400407703ba5775be4891a053916ffdb96b6b4b7
  [PieterBruegel_b3.webp]=91f21334c83318b33a33412881f52c80810379d6fda4807890c9571b1ade57ca
  [PieterBruegel_b4.webp]=ce0c070a7032f0fa79036c5beda564e7d982e06dc38c507c0b89f1c0099efe18
  [PieterBruegel_c1.webp]=db8e05766bd584e6b5704c90909d0ec0c0d3ada4d23830eb0023bd447c5cf552
  [PieterBruegel_c2.webp]=9f03cd588e44ac0ba72c92b6f29b4061be4f6ba1d2c91e5891c5f080d21a6849
  [PieterBruegel_c3.webp]=a1799ca12d66a0ede888df6429a8a248129f3f989aa5e566e52ecd6a063b984b
  [PieterBruegel_c4.webp]=aa71b92f261c9ed45219f07298a1b5390e20bc8d8944f4ef30911f002bf90012
  [PieterBruegel_d1.webp]=f43fc7f9c0aad0faafc411742a8664e251265a263e8498bb6d360281a2066e50
  [PieterBruegel_d2.webp]=2f5d8201fc9263b8c9897a0458db729ef8a03cc7fef7e9088c55b8835c87ec82
  [PieterBruegel_d3.webp]=98c1bcea85f6bb3196e8e351d137260bfc25e1cdd6c10e567a16beecec297645
  [PieterBruegel_d4.webp]=f24b546bf28b20e989c0f97a85c2773f9a9c4f038e4e8236597a5e6f3510a413
)

log() { echo "setup-styles: $*" >&2; }

PY=python3
command -v "$PY" >/dev/null 2>&1 || PY=python

file_ok() { # path expected-hash
  [[ -f "$1" ]] && [[ "$(sha256sum "$1" | cut -d' ' -f1)" == "$2" ]]
}

all_present() {
  local name
  for name in "${!SHA256[@]}"; do
    file_ok "$STYLES_DIR/$name" "${SHA256[$name]}" || return 1
  done
}

# Qt resource file (rcc, format 1-3) reader: writes the named files found anywhere in it.
extract_rcc() { # rcc-file out-dir names...
  "$PY" - "$@" <<'PYEOF'
import struct, sys, zlib, os
path, out, wanted = sys.argv[1], sys.argv[2], set(sys.argv[3:])
b = open(path, 'rb').read()
if b[:4] != b'qres':
    sys.exit(f"{path}: not a Qt resource file")
ver, tree, data, names = struct.unpack('>IIII', b[4:20])
node = 22 if ver >= 2 else 14
def name(off):
    n, _ = struct.unpack('>HI', b[names + off:names + off + 6])
    return b[names + off + 6:names + off + 6 + 2 * n].decode('utf-16-be')
found = set()
stack = [0]
while stack:
    i = stack.pop()
    o = tree + i * node
    noff, flags = struct.unpack('>IH', b[o:o + 6])
    if flags & 2:
        cnt, first = struct.unpack('>II', b[o + 6:o + 14])
        stack.extend(range(first, first + cnt))
        continue
    nm = name(noff)
    if nm not in wanted:
        continue
    doff, = struct.unpack('>I', b[o + 10:o + 14])
    sz, = struct.unpack('>I', b[data + doff:data + doff + 4])
    blob = b[data + doff + 4:data + doff + 4 + sz]
    if flags & 1:
        blob = zlib.decompress(blob[4:])
    elif flags & 4:
        sys.exit(f"{path}: {nm} is zstd-compressed; not supported")
    with open(os.path.join(out, nm), 'wb') as f:
        f.write(blob)
    found.add(nm)
missing = wanted - found
if missing:
    sys.exit(f"{path}: missing {', '.join(sorted(missing))}")
PYEOF
}

fetch_paintings() {
  local tmp rcc
  tmp="$(mktemp -d)"
  # shellcheck disable=SC2064
  trap "rm -rf '$tmp'" EXIT
  if file_ok "/$RCC_IN_PACKAGE" "$RCC_SHA256"; then
    rcc="/$RCC_IN_PACKAGE"
  else
    log "downloading Debian package gcompris-qt-data (44 MB)"
    if ! (cd "$tmp" && apt-get download gcompris-qt-data >/dev/null 2>&1); then
      # An old package list may not know the package yet.
      (apt-get update -qq >/dev/null 2>&1 || true)
      (cd "$tmp" && apt-get download gcompris-qt-data >/dev/null) || { log "error: apt-get download gcompris-qt-data failed"; return 1; }
    fi
    dpkg-deb --fsys-tarfile "$tmp"/gcompris-qt-data_*.deb | tar -x -C "$tmp" "./$RCC_IN_PACKAGE"
    rcc="$tmp/$RCC_IN_PACKAGE"
    if ! file_ok "$rcc" "$RCC_SHA256"; then
      log "warning: paintings.rcc differs from the known version ($(sha256sum "$rcc" | cut -d' ' -f1)); checking the paintings themselves"
    fi
  fi
  mkdir -p "$tmp/out" "$STYLES_DIR"
  extract_rcc "$rcc" "$tmp/out" "${!SHA256[@]}"
  local name
  for name in "${!SHA256[@]}"; do
    if ! file_ok "$tmp/out/$name" "${SHA256[$name]}"; then
      log "error: $name has SHA-256 $(sha256sum "$tmp/out/$name" | cut -d' ' -f1), expected ${SHA256[$name]}"
      return 1
    fi
    cp "$tmp/out/$name" "$STYLES_DIR/.$name.tmp"
    mv -f "$STYLES_DIR/.$name.tmp" "$STYLES_DIR/$name"
  done
}

if all_present; then
  log "paintings already in $STYLES_DIR"
else
  fetch_paintings || exit 1
  all_present || { log "error: paintings in $STYLES_DIR still fail verification"; exit 1; }
  log "paintings installed in $STYLES_DIR"
fi
echo "$STYLES_DIR"
