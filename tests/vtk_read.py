"""Read ballast's VTK files back with VTK's own readers and print what they hold as JSON.

Usage: vtk_read.py FILE...   (each FILE a .vtu or a .pvd)

Called by tests/vtk_readback.rs. Floating-point values are printed as their IEEE-754 bit
patterns (unsigned 64-bit integers) so that the Rust side can compare them bit for bit.
Any error or warning that VTK reports makes the script exit with status 1.
"""

import json
import os
import sys

import numpy as np
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
from vtkmodules.vtkIOXMLParser import vtkXMLDataParser

# Collect VTK's messages instead of letting them go to the terminal unnoticed.
MESSAGES = vtkStringOutputWindow()
vtkOutputWindow.SetInstance(MESSAGES)


def fail(message):
    print(message, file=sys.stderr)
    sys.exit(1)


def check_messages(path):
    text = MESSAGES.GetOutput()
    if text.strip():
        fail(f"{path}: VTK reported: {text.strip()}")


def array_values(array):
    values = vtk_to_numpy(array)
    if values.dtype == np.float64:
        return np.ascontiguousarray(values).reshape(-1).view(np.uint64).tolist()
    if values.dtype.kind in "iu":
        return values.reshape(-1).astype(np.int64).tolist()
    fail(f"unexpected array type {values.dtype} for {array.GetName()}")


def arrays(data):
    result = []
    for i in range(data.GetNumberOfArrays()):
        array = data.GetArray(i)
        result.append(
            {
                "name": array.GetName(),
                "type": array.GetDataTypeAsString(),
                "components": array.GetNumberOfComponents(),
                "tuples": array.GetNumberOfTuples(),
                "values": array_values(array),
            }
        )
    return result


def read_vtu(path):
    if not os.path.isfile(path):
        fail(f"{path}: no such file")
    reader = vtkXMLUnstructuredGridReader()
    if not reader.CanReadFile(path):
        fail(f"{path}: vtkXMLUnstructuredGridReader cannot read it")
    reader.SetFileName(path)
    reader.Update()
    check_messages(path)
    grid = reader.GetOutput()
    points = grid.GetPoints()
    cells = grid.GetCells()
    n_cells = grid.GetNumberOfCells()
    return {
        "kind": "vtu",
        "n_points": grid.GetNumberOfPoints(),
        "n_cells": n_cells,
        "points_type": points.GetData().GetDataTypeAsString() if points else None,
        "points": array_values(points.GetData()) if points else [],
        "cell_types": [grid.GetCellType(i) for i in range(n_cells)],
        "connectivity": array_values(cells.GetConnectivityArray()) if cells else [],
        "offsets": array_values(cells.GetOffsetsArray()) if cells else [],
        "point_data": arrays(grid.GetPointData()),
        "cell_data": arrays(grid.GetCellData()),
        "active_vectors": name_of(grid.GetPointData().GetVectors()),
        "active_tensors": name_of(grid.GetCellData().GetTensors()),
    }


def name_of(array):
    return array.GetName() if array is not None else None


def read_pvd(path):
    # The vtk wheel has no vtkPVDReader (it is ParaView's); parse the collection with
    # VTK's XML parser, as ParaView's reader does, and read each frame with VTK.
    parser = vtkXMLDataParser()
    parser.SetFileName(path)
    if not parser.Parse():
        fail(f"{path}: vtkXMLDataParser failed")
    check_messages(path)
    root = parser.GetRootElement()
    if root.GetName() != "VTKFile" or root.GetAttribute("type") != "Collection":
        fail(f"{path}: root is not a VTKFile of type Collection")
    collection = root.FindNestedElementWithName("Collection")
    if collection is None:
        fail(f"{path}: no Collection element")
    base = os.path.dirname(path)
    frames = []
    for i in range(collection.GetNumberOfNestedElements()):
        element = collection.GetNestedElement(i)
        if element.GetName() != "DataSet":
            continue
        time = float(element.GetAttribute("timestep"))
        file = element.GetAttribute("file")
        frames.append(
            {
                "time_bits": int(np.array([time]).view(np.uint64)[0]),
                "file": file,
                "frame": read_vtu(os.path.join(base, file)),
            }
        )
    return {"kind": "pvd", "frames": frames}


def main():
    if len(sys.argv) < 2:
        fail(__doc__)
    result = {}
    for path in sys.argv[1:]:
        if path.endswith(".pvd"):
            result[path] = read_pvd(path)
        elif path.endswith(".vtu"):
            result[path] = read_vtu(path)
        else:
            fail(f"{path}: expected a .vtu or .pvd file")
    json.dump(result, sys.stdout)


if __name__ == "__main__":
    main()
