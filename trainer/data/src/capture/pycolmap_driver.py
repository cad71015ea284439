# snerf capture's pycolmap backend: COLMAP's features, matching, mapping and undistortion
# through PyPI's pycolmap (COLMAP 4.x bindings), on the CPU. snerf writes this file into its
# work folder and runs it with the setup step's Python (scripts/setup-capture.sh). It prints
# "snerf-phase NAME TOTAL" when a phase starts and "snerf-done K" as it advances; everything else
# on stdout/stderr is pycolmap's log. Arguments: a JSON object (see `capture::pycolmap`).
import json
import sys

import pycolmap


def main():
    a = json.loads(sys.argv[1])
    cpu = pycolmap.Device.cpu
    n = a.get("photos", 0)

    def phase(name, total):
        print(f"snerf-phase {name} {total}", flush=True)

    def done(k):
        print(f"snerf-done {k}", flush=True)

    if a["step"] == "map":
        reader = pycolmap.ImageReaderOptions()
        reader.camera_model = a["camera_model"]
        if a.get("camera_params"):
            reader.camera_params = a["camera_params"]
        ext = pycolmap.FeatureExtractionOptions()
        ext.num_threads = a["threads"]
        ext.sift.max_num_features = a["max_features"]
        if a["max_size"] > 0:
            ext.max_image_size = a["max_size"]
        phase("features", n)
        pycolmap.extract_features(
            a["database"], a["images"],
            camera_mode=pycolmap.CameraMode.SINGLE if a["single_camera"] else pycolmap.CameraMode.PER_IMAGE,
            reader_options=reader, extraction_options=ext, device=cpu)
        done(n)

        match = pycolmap.FeatureMatchingOptions()
        match.num_threads = a["threads"]
        if a["matcher"] == "exhaustive":
            phase("matching", 1)
            pycolmap.match_exhaustive(a["database"], matching_options=match, device=cpu)
        else:
            phase("matching", 1)
            pairing = pycolmap.SequentialPairingOptions()
            pairing.overlap = a["overlap"]
            pycolmap.match_sequential(a["database"], matching_options=match, pairing_options=pairing, device=cpu)
        done(1)

        opts = pycolmap.IncrementalPipelineOptions()
        opts.num_threads = a["threads"]
        if a.get("seed") is not None:
            opts.random_seed = a["seed"]
        if a.get("camera_params"):
            opts.ba_refine_focal_length = False
        phase("mapping", n)
        registered = [0]

        def next_image():
            registered[0] += 1
            done(registered[0])

        models = pycolmap.incremental_mapping(
            a["database"], a["images"], a["sparse"], options=opts, next_image_callback=next_image)
        best = max(models.values(), key=lambda r: r.num_reg_images(), default=None)
        if best is not None:
            print(f"Mean reprojection error: {best.compute_mean_reprojection_error()}px", flush=True)
    elif a["step"] == "undistort":
        phase("undistortion", 1)
        pycolmap.undistort_images(a["output"], a["model"], a["images"], output_type="COLMAP",
                                  num_threads=a["threads"])
        done(1)
    else:
        sys.exit(f"unknown step {a['step']}")


if __name__ == "__main__":
    main()
