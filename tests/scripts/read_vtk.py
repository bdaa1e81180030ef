"""Reads a .pvd collection and every .vti file it lists with VTK's own XML readers, and prints
them as JSON: [{"time", "file", "dimensions", "origin", "spacing", "u"}]. Used by
tests/vtk_output.rs to check nlsolve's VTK files against the field it writes raw."""

import json
import sys
from pathlib import Path

from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOXML import vtkXMLImageDataReader
import xml.etree.ElementTree as ElementTree

collection = Path(sys.argv[1])
frames = []
for dataset in ElementTree.parse(collection).getroot().iter("DataSet"):
    reader = vtkXMLImageDataReader()
    reader.SetFileName(str(collection.parent / dataset.get("file")))
    reader.Update()
    if reader.GetErrorCode() != 0:
        sys.exit(f"VTK cannot read {dataset.get('file')}")
    image = reader.GetOutput()
    values = image.GetPointData().GetArray("u")
    frames.append(
        {
            "time": float(dataset.get("timestep")),
            "file": dataset.get("file"),
            "dimensions": list(image.GetDimensions()),
            "origin": list(image.GetOrigin()),
            "spacing": list(image.GetSpacing()),
            "u": vtk_to_numpy(values).tolist() if values is not None else None,
        }
    )
print(json.dumps(frames))
