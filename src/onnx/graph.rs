//! A small ONNX graph builder: nodes in topological order, weights as initializers taken from a
//! module's named tensors, shapes of the graph's inputs and outputs. Node and value names
//! follow the module paths (`encoder.0.conv1`, …) so an exported graph reads like the model.

use super::proto::{
    self, AttributeProto, AttributeType, GraphProto, NodeProto, TensorProto, TensorShapeProto,
    TypeProto, ValueInfoProto, tensor_shape_proto::Dimension,
    tensor_shape_proto::dimension::Value as DimValue, type_proto,
};
use crate::error::{Error, Result};
use burn::module::Module;
use burn::store::{BurnToPyTorchAdapter, ModuleSnapshot};
use burn::tensor::TensorData;
use std::collections::{BTreeMap, BTreeSet};

/// One axis of a graph input or output: a fixed size or a named symbol.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Dim {
    Fixed(usize),
    Symbol(&'static str),
}

/// A named f32 tensor of the module (row-major).
#[derive(Clone, Debug)]
pub struct Weight {
    pub shape: Vec<usize>,
    pub data: Vec<f32>,
}

/// Every parameter and BatchNorm running statistic of `module`, by its PyTorch-style path
/// (`models::import::expected_tensors` names: BatchNorm γ/β are `weight`/`bias`).
pub fn module_weights<M: Module>(module: &M) -> Result<BTreeMap<String, Weight>> {
    let mut out = BTreeMap::new();
    for snap in module.collect(None, Some(Box::new(BurnToPyTorchAdapter)), true) {
        // Non-float tensors (BatchNorm's training flag) are no weights of the inference graph.
        if !snap.dtype.is_float() {
            continue;
        }
        let (name, dtype, shape, _, bytes) = snap
            .into_parts()
            .map_err(|e| Error::Invalid(format!("reading a model weight: {e:?}")))?;
        let data = TensorData::from_bytes(bytes, shape.clone(), dtype)
            .convert::<f32>()
            .try_into_vec::<f32>()
            .map_err(|e| Error::Invalid(format!("reading weight '{name}': {e:?}")))?;
        out.insert(
            name,
            Weight {
                shape: shape.to_vec(),
                data,
            },
        );
    }
    Ok(out)
}

pub struct GraphBuilder {
    weights: BTreeMap<String, Weight>,
    used: BTreeSet<String>,
    nodes: Vec<NodeProto>,
    initializers: Vec<TensorProto>,
    inputs: Vec<ValueInfoProto>,
    outputs: Vec<ValueInfoProto>,
    names: BTreeSet<String>,
}

fn attr(name: &str, ty: AttributeType) -> AttributeProto {
    AttributeProto {
        name: Some(name.into()),
        r#type: Some(ty as i32),
        ..Default::default()
    }
}

/// An integer-list attribute.
pub fn ints(name: &str, v: &[i64]) -> AttributeProto {
    AttributeProto {
        ints: v.to_vec(),
        ..attr(name, AttributeType::Ints)
    }
}

/// An integer attribute.
pub fn int(name: &str, v: i64) -> AttributeProto {
    AttributeProto {
        i: Some(v),
        ..attr(name, AttributeType::Int)
    }
}

/// A float attribute.
pub fn float(name: &str, v: f32) -> AttributeProto {
    AttributeProto {
        f: Some(v),
        ..attr(name, AttributeType::Float)
    }
}

/// A string attribute.
pub fn string(name: &str, v: &str) -> AttributeProto {
    AttributeProto {
        s: Some(v.as_bytes().to_vec()),
        ..attr(name, AttributeType::String)
    }
}

fn value_info(name: &str, dims: &[Dim]) -> ValueInfoProto {
    let dim = dims
        .iter()
        .map(|d| Dimension {
            value: Some(match d {
                Dim::Fixed(n) => DimValue::DimValue(*n as i64),
                Dim::Symbol(s) => DimValue::DimParam((*s).into()),
            }),
        })
        .collect();
    ValueInfoProto {
        name: Some(name.into()),
        r#type: Some(TypeProto {
            value: Some(type_proto::Value::TensorType(type_proto::Tensor {
                elem_type: Some(proto::FLOAT),
                shape: Some(TensorShapeProto { dim }),
            })),
        }),
        doc_string: None,
    }
}

impl GraphBuilder {
    pub fn new(weights: BTreeMap<String, Weight>) -> GraphBuilder {
        GraphBuilder {
            weights,
            used: BTreeSet::new(),
            nodes: Vec::new(),
            initializers: Vec::new(),
            inputs: Vec::new(),
            outputs: Vec::new(),
            names: BTreeSet::new(),
        }
    }

    /// A fresh value name: `base`, else `base_2`, `base_3`, …
    fn fresh(&mut self, base: &str) -> String {
        let mut name = base.to_string();
        let mut k = 2;
        while self.names.contains(&name) {
            name = format!("{base}_{k}");
            k += 1;
        }
        self.names.insert(name.clone());
        name
    }

    /// Declares a float graph input.
    pub fn input(&mut self, name: &str, dims: &[Dim]) -> String {
        let name = self.fresh(name);
        self.inputs.push(value_info(&name, dims));
        name
    }

    /// Declares `value` a graph output named `name` (an Identity node renames it).
    pub fn output(&mut self, value: &str, name: &str, dims: &[Dim]) -> Result<()> {
        let name = self.fresh(name);
        self.nodes.push(NodeProto {
            input: vec![value.into()],
            output: vec![name.clone()],
            name: Some(name.clone()),
            op_type: Some("Identity".into()),
            ..Default::default()
        });
        self.outputs.push(value_info(&name, dims));
        Ok(())
    }

    /// A node with one output named after `name`; returns the output's name.
    pub fn node(
        &mut self,
        op: &str,
        name: &str,
        inputs: &[&str],
        attribute: Vec<AttributeProto>,
    ) -> String {
        let out = self.fresh(name);
        self.nodes.push(NodeProto {
            input: inputs.iter().map(|s| s.to_string()).collect(),
            output: vec![out.clone()],
            name: Some(out.clone()),
            op_type: Some(op.into()),
            domain: None,
            attribute,
        });
        out
    }

    /// Whether the module has a weight of this name.
    pub fn has(&self, name: &str) -> bool {
        self.weights.contains_key(name)
    }

    /// The module's weight `name` as an initializer (added once); returns its name.
    pub fn weight(&mut self, name: &str) -> Result<String> {
        let w = self
            .weights
            .get(name)
            .ok_or_else(|| {
                Error::Invalid(format!("ONNX export: the model has no weight '{name}'"))
            })?
            .clone();
        if self.used.insert(name.to_string()) {
            self.names.insert(name.to_string());
            self.initializers.push(TensorProto {
                dims: w.shape.iter().map(|&d| d as i64).collect(),
                data_type: Some(proto::FLOAT),
                float_data: w.data,
                name: Some(name.into()),
                ..Default::default()
            });
        }
        Ok(name.to_string())
    }

    /// A constant f32 initializer.
    pub fn const_f32(&mut self, name: &str, dims: &[usize], data: Vec<f32>) -> String {
        let name = self.fresh(name);
        self.initializers.push(TensorProto {
            dims: dims.iter().map(|&d| d as i64).collect(),
            data_type: Some(proto::FLOAT),
            float_data: data,
            name: Some(name.clone()),
            ..Default::default()
        });
        name
    }

    /// A constant int64 initializer.
    pub fn const_i64(&mut self, name: &str, dims: &[usize], data: Vec<i64>) -> String {
        let name = self.fresh(name);
        self.initializers.push(TensorProto {
            dims: dims.iter().map(|&d| d as i64).collect(),
            data_type: Some(proto::INT64),
            int64_data: data,
            name: Some(name.clone()),
            ..Default::default()
        });
        name
    }

    /// A scalar f32 constant (broadcasts in element-wise ops).
    pub fn scalar(&mut self, name: &str, v: f32) -> String {
        self.const_f32(name, &[], vec![v])
    }

    /// `Conv` with the module's `{prefix}.weight` (and `{prefix}.bias` if it has one); `pads`
    /// are ONNX's [top, left, bottom, right].
    pub fn conv(
        &mut self,
        prefix: &str,
        x: &str,
        stride: usize,
        pads: [usize; 4],
    ) -> Result<String> {
        let w = self.weight(&format!("{prefix}.weight"))?;
        let shape = self.weights[&w].shape.clone();
        let mut inputs = vec![x.to_string(), w];
        if self.has(&format!("{prefix}.bias")) {
            inputs.push(self.weight(&format!("{prefix}.bias"))?);
        }
        let refs: Vec<&str> = inputs.iter().map(String::as_str).collect();
        Ok(self.node(
            "Conv",
            prefix,
            &refs,
            vec![
                ints("kernel_shape", &[shape[2] as i64, shape[3] as i64]),
                ints("strides", &[stride as i64, stride as i64]),
                ints("pads", &pads.map(|p| p as i64)),
                ints("dilations", &[1, 1]),
                int("group", 1),
            ],
        ))
    }

    /// `ConvTranspose` with the module's `{prefix}.weight` ([in, out, kh, kw], ONNX's layout
    /// too) and bias; `pads` [top, left, bottom, right] crop the full output, `output_padding`
    /// adds rows/columns at the bottom/right.
    pub fn conv_transpose(
        &mut self,
        prefix: &str,
        x: &str,
        stride: usize,
        pads: [usize; 4],
        output_padding: usize,
    ) -> Result<String> {
        let w = self.weight(&format!("{prefix}.weight"))?;
        let shape = self.weights[&w].shape.clone();
        let mut inputs = vec![x.to_string(), w];
        if self.has(&format!("{prefix}.bias")) {
            inputs.push(self.weight(&format!("{prefix}.bias"))?);
        }
        let refs: Vec<&str> = inputs.iter().map(String::as_str).collect();
        let op = output_padding as i64;
        Ok(self.node(
            "ConvTranspose",
            prefix,
            &refs,
            vec![
                ints("kernel_shape", &[shape[2] as i64, shape[3] as i64]),
                ints("strides", &[stride as i64, stride as i64]),
                ints("pads", &pads.map(|p| p as i64)),
                ints("output_padding", &[op, op]),
                ints("dilations", &[1, 1]),
                int("group", 1),
            ],
        ))
    }

    /// Inference `BatchNormalization` with the module's `{prefix}.weight/bias/running_mean/
    /// running_var` (γ, β, mean, variance).
    pub fn batch_norm(&mut self, prefix: &str, x: &str, epsilon: f64) -> Result<String> {
        let names = ["weight", "bias", "running_mean", "running_var"]
            .map(|k| self.weight(&format!("{prefix}.{k}")));
        let [g, b, m, v] = names;
        let (g, b, m, v) = (g?, b?, m?, v?);
        Ok(self.node(
            "BatchNormalization",
            prefix,
            &[x, &g, &b, &m, &v],
            vec![float("epsilon", epsilon as f32)],
        ))
    }

    /// `Pad(mode = reflect)` of the last two axes by ([top, bottom], [left, right]) (TensorFlow's
    /// `REFLECT`: the edge sample is not repeated). ONNX Runtime needs each pad < the axis.
    pub fn pad_reflect(
        &mut self,
        name: &str,
        x: &str,
        (t, b): (usize, usize),
        (l, r): (usize, usize),
    ) -> String {
        if t + b + l + r == 0 {
            return x.to_string();
        }
        let pads = self.const_i64(
            &format!("{name}.pads"),
            &[8],
            vec![0, 0, t as i64, l as i64, 0, 0, b as i64, r as i64],
        );
        self.node("Pad", name, &[x, &pads], vec![string("mode", "reflect")])
    }

    pub fn relu(&mut self, name: &str, x: &str) -> String {
        self.node("Relu", name, &[x], vec![])
    }

    pub fn leaky_relu(&mut self, name: &str, x: &str, alpha: f64) -> String {
        self.node("LeakyRelu", name, &[x], vec![float("alpha", alpha as f32)])
    }

    pub fn concat(&mut self, name: &str, xs: &[&str], axis: i64) -> String {
        self.node("Concat", name, xs, vec![int("axis", axis)])
    }

    /// Element-wise `op` (Add, Sub, Mul, Div, Pow) of a value and an f32 scalar constant.
    pub fn with_scalar(&mut self, op: &str, name: &str, x: &str, v: f32) -> String {
        let c = self.scalar(&format!("{name}.c"), v);
        self.node(op, name, &[x, &c], vec![])
    }

    /// The finished graph; fails if a module weight went unused (the export would not be the
    /// module).
    pub fn finish(self, name: &str) -> Result<GraphProto> {
        let unused: Vec<&String> = self
            .weights
            .keys()
            .filter(|k| !self.used.contains(*k))
            .collect();
        if !unused.is_empty() {
            return Err(Error::Invalid(format!(
                "ONNX export: {} model weights have no place in the graph (first: {:?})",
                unused.len(),
                unused[0]
            )));
        }
        Ok(GraphProto {
            node: self.nodes,
            name: Some(name.into()),
            initializer: self.initializers,
            doc_string: None,
            input: self.inputs,
            output: self.outputs,
        })
    }
}
