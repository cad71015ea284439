//! `onnx:FILE`: generic image-to-image models, written here as tiny hand-made ONNX files
//! (through tract-onnx's protobuf types), plus every kind of bad file.

mod stylizer_support;

use std::path::{Path, PathBuf};

use prost::Message;
use snerf_stylize::stylizer::{from_spec, models_dir, Image, StylizerOptions};
use stylizer_support::{content_image, models_or_skip};
use tract_onnx::pb::{
    tensor_shape_proto::{dimension, Dimension},
    type_proto, GraphProto, ModelProto, NodeProto, OperatorSetIdProto, TensorProto, TensorShapeProto, TypeProto,
    ValueInfoProto,
};

const FLOAT: i32 = 1;

fn dim(d: &str) -> Dimension {
    let value = match d.parse::<i64>() {
        Ok(n) => dimension::Value::DimValue(n),
        Err(_) => dimension::Value::DimParam(d.to_string()),
    };
    Dimension { value: Some(value), ..Default::default() }
}

fn value_info(name: &str, dims: &[&str]) -> ValueInfoProto {
    ValueInfoProto {
        name: name.into(),
        r#type: Some(TypeProto {
            value: Some(type_proto::Value::TensorType(type_proto::Tensor {
                elem_type: FLOAT,
                shape: Some(TensorShapeProto { dim: dims.iter().map(|d| dim(d)).collect() }),
            })),
            ..Default::default()
        }),
        ..Default::default()
    }
}

fn scalar(name: &str, v: f32) -> TensorProto {
    TensorProto { name: name.into(), data_type: FLOAT, float_data: vec![v], ..Default::default() }
}

fn node(op: &str, inputs: &[&str], output: &str) -> NodeProto {
    NodeProto {
        op_type: op.into(),
        name: format!("{op}_{output}"),
        input: inputs.iter().map(|s| s.to_string()).collect(),
        output: vec![output.into()],
        ..Default::default()
    }
}

/// A one-input model: `nodes` from "image" to "out", with scalar constants.
fn write_model(dir: &Path, file: &str, input_dims: &[&str], nodes: Vec<NodeProto>, consts: &[(&str, f32)]) -> PathBuf {
    let model = ModelProto {
        ir_version: 8,
        opset_import: vec![OperatorSetIdProto { domain: String::new(), version: 13 }],
        graph: Some(GraphProto {
            name: "g".into(),
            node: nodes,
            initializer: consts.iter().map(|(n, v)| scalar(n, *v)).collect(),
            input: vec![value_info("image", input_dims)],
            output: vec![value_info("out", &[])],
            ..Default::default()
        }),
        ..Default::default()
    };
    // Output shape left empty: tract infers it.
    let mut model = model;
    model.graph.as_mut().unwrap().output[0].r#type = None;
    let path = dir.join(file);
    std::fs::write(&path, model.encode_to_vec()).unwrap();
    path
}

fn invert_model(dir: &Path, file: &str, dims: &[&str]) -> PathBuf {
    write_model(dir, file, dims, vec![node("Sub", &["one", "image"], "out")], &[("one", 1.0)])
}

fn spec(path: &Path) -> String {
    format!("onnx:{}", path.display())
}

fn assert_close_to_inverse(content: &Image, out: &Image, tol: f32) {
    assert_eq!((out.width, out.height), (content.width, content.height));
    let worst = content.data.iter().zip(&out.data).map(|(c, o)| (1.0 - c - o).abs()).fold(0.0f32, f32::max);
    assert!(worst < tol, "output is not 1 - content (worst error {worst})");
}

#[test]
fn nchw_symbolic_model_runs_at_view_size() {
    let dir = tempfile::tempdir().unwrap();
    let path = invert_model(dir.path(), "invert.onnx", &["1", "3", "h", "w"]);
    let s = from_spec(&spec(&path), None, &StylizerOptions::default()).unwrap();
    assert!(s.name().contains("invert.onnx"));
    // 90x70 is not a multiple of 32: padded, run, cropped.
    let content = content_image(90, 70);
    assert_close_to_inverse(&content, &s.stylize(&content).unwrap(), 1e-5);
}

#[test]
fn nhwc_model_and_minus_one_one_range() {
    let dir = tempfile::tempdir().unwrap();
    // Neg in [-1,1] space is 1 - v in [0,1] space.
    let path = write_model(dir.path(), "neg.onnx", &["1", "h", "w", "3"], vec![node("Neg", &["image"], "out")], &[]);
    let s = from_spec(&format!("{}?range=-1,1", spec(&path)), None, &StylizerOptions::default()).unwrap();
    let content = content_image(40, 33);
    assert_close_to_inverse(&content, &s.stylize(&content).unwrap(), 1e-5);
    // The same model in the default [0,1] range clamps everything to 0.
    let s = from_spec(&spec(&path), None, &StylizerOptions::default()).unwrap();
    assert!(s.stylize(&content).unwrap().data.iter().all(|v| *v == 0.0));
}

#[test]
fn fixed_size_model_is_resized_to_and_back() {
    let dir = tempfile::tempdir().unwrap();
    let path = invert_model(dir.path(), "fixed.onnx", &["1", "3", "64", "64"]);
    let s = from_spec(&spec(&path), None, &StylizerOptions::default()).unwrap();
    let content = Image::filled(120, 50, [0.2, 0.5, 0.7]);
    let out = s.stylize(&content).unwrap();
    assert_close_to_inverse(&content, &out, 1e-4);
}

#[test]
fn strength_blends_with_content() {
    let dir = tempfile::tempdir().unwrap();
    let path = invert_model(dir.path(), "invert.onnx", &["1", "3", "h", "w"]);
    let opts = StylizerOptions { strength: 0.25, ..Default::default() };
    let s = from_spec(&spec(&path), None, &opts).unwrap();
    let content = Image::filled(32, 32, [0.2, 0.4, 1.0]);
    let out = s.stylize(&content).unwrap();
    for (c, o) in content.data.iter().zip(&out.data) {
        assert!((o - (0.75 * c + 0.25 * (1.0 - c))).abs() < 1e-5);
    }
}

#[test]
fn nan_output_is_an_error_naming_the_stylizer() {
    let dir = tempfile::tempdir().unwrap();
    // log(x - 2) is NaN for every x in [0, 1].
    let path = write_model(
        dir.path(),
        "nan.onnx",
        &["1", "3", "h", "w"],
        vec![node("Sub", &["image", "two"], "t"), node("Log", &["t"], "out")],
        &[("two", 2.0)],
    );
    let s = from_spec(&spec(&path), None, &StylizerOptions::default()).unwrap();
    let err = s.stylize(&content_image(48, 40)).unwrap_err().to_string();
    assert!(err.contains("nan.onnx") && err.contains("NaN") && err.contains("48x40"), "{err}");
}

fn expect_error(path: &Path, needles: &[&str]) {
    let err = match from_spec(&spec(path), None, &StylizerOptions::default()) {
        Ok(_) => panic!("{} was accepted", path.display()),
        Err(e) => format!("{e:#}"),
    };
    assert!(err.contains(&path.display().to_string()), "error does not name the file: {err}");
    for n in needles {
        assert!(err.contains(n), "error lacks {n:?}: {err}");
    }
}

#[test]
fn bad_files_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let corrupt = dir.path().join("corrupt.onnx");
    std::fs::write(&corrupt, (0..4000u32).map(|i| (i.wrapping_mul(2654435761) >> 13) as u8).collect::<Vec<u8>>()).unwrap();
    expect_error(&corrupt, &["not a valid ONNX model"]);

    let text = dir.path().join("notes.onnx");
    std::fs::write(&text, "this is a text file, not a model\n").unwrap();
    expect_error(&text, &["not a valid ONNX model"]);

    let empty = dir.path().join("empty.onnx");
    std::fs::write(&empty, b"").unwrap();
    expect_error(&empty, &["empty"]);

    expect_error(&dir.path().join("missing.onnx"), &["does not exist"]);

    // A truncated copy of a valid model.
    let good = invert_model(dir.path(), "good.onnx", &["1", "3", "h", "w"]);
    let bytes = std::fs::read(&good).unwrap();
    let truncated = dir.path().join("truncated.onnx");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    expect_error(&truncated, &["not a valid ONNX model"]);

    let rank2 = write_model(dir.path(), "rank2.onnx", &["1", "n"], vec![node("Neg", &["image"], "out")], &[]);
    expect_error(&rank2, &["rank 2", "image"]);

    let gray = write_model(dir.path(), "gray.onnx", &["1", "1", "h", "w"], vec![node("Neg", &["image"], "out")], &[]);
    expect_error(&gray, &["layout"]);

    let batch = invert_model(dir.path(), "batch4.onnx", &["4", "3", "h", "w"]);
    expect_error(&batch, &["batch size 4"]);
}

#[test]
fn two_input_model_is_rejected_with_its_inputs_listed() {
    let Some(opts) = models_or_skip("two_input_model_is_rejected_with_its_inputs_listed") else { return };
    for file in ["multistyle26.onnx", "arbitrary_transform.onnx"] {
        let path = models_dir(&opts).join(file);
        expect_error(&path, &["2 inputs", "exactly one image input"]);
    }
}

#[test]
fn unknown_range_is_an_error() {
    let err = from_spec("onnx:model.onnx?range=0,2", None, &StylizerOptions::default()).err().unwrap().to_string();
    assert!(err.contains("range"), "{err}");
}
