#!/usr/bin/env python3
"""Writes a tiny ONNX place-descriptor network for the ONNX backend test:
input [1, 3, 8, 8] -> GlobalAveragePool -> Flatten -> MatMul(W, 3 x 4) ->
output [1, 4]. W is fixed below so the test can compute the same by hand."""
import sys

import onnx
from onnx import TensorProto, helper

W = [[1.0, 0.0, 2.0, -1.0],
     [0.0, 1.0, 1.0, 0.5],
     [0.5, -1.0, 0.0, 1.0]]

def main(path):
    x = helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, 8, 8])
    y = helper.make_tensor_value_info("descriptor", TensorProto.FLOAT, [1, 4])
    w = helper.make_tensor("W", TensorProto.FLOAT, [3, 4], [v for row in W for v in row])
    nodes = [
        helper.make_node("GlobalAveragePool", ["image"], ["pooled"]),
        helper.make_node("Flatten", ["pooled"], ["flat"], axis=1),
        helper.make_node("MatMul", ["flat", "W"], ["descriptor"]),
    ]
    graph = helper.make_graph(nodes, "tiny_place", [x], [y], [w])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 12)])
    model.ir_version = 7
    onnx.checker.check_model(model)
    onnx.save(model, path)

if __name__ == "__main__":
    main(sys.argv[1])
