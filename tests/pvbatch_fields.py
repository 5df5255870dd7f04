"""Run by pvbatch (tests/test_outputs.py): open a fields.xdmf with ParaView's default reader
and print, as JSON, what every block holds at every time, then apply the recipe of docs/outputs.md
(colour by sigma_zz, Warp By Vector) and print the colour range it gets.

    pvbatch tests/pvbatch_fields.py RUN/fields.xdmf [FIELD]

FIELD: the cell field to colour by (sigma_zz; a plane-strain run's sigma_yy).
"""
import json
import sys

from paraview import simple, servermanager

FIELD = sys.argv[2] if len(sys.argv) > 2 else "sigma_zz"
reader = simple.OpenDataFile(sys.argv[1])  # the reader ParaView picks for the file
reader.UpdatePipelineInformation()
times = [float(t) for t in reader.TimestepValues]
steps = []
for t in times:
    reader.UpdatePipeline(t)
    data = servermanager.Fetch(reader)
    blocks = []
    it = data.NewIterator()
    it.InitTraversal()
    while not it.IsDoneWithTraversal():
        b = it.GetCurrentDataObject()
        arrays = {}
        for kind, fd in (("point", b.GetPointData()), ("cell", b.GetCellData())):
            for i in range(fd.GetNumberOfArrays()):
                a = fd.GetArray(i)
                arrays[a.GetName()] = {"where": kind, "components": a.GetNumberOfComponents(),
                                       "range": list(a.GetRange(-1 if a.GetNumberOfComponents() > 1 else 0))}
        blocks.append({"cells": b.GetNumberOfCells(), "points": b.GetNumberOfPoints(),
                       "arrays": arrays})
        it.GoToNextItem()
    steps.append({"time": t, "blocks": blocks})

# the recipe: Apply, colour by sigma_zz, Warp By Vector (last time)
view = simple.CreateRenderView()
view.ViewTime = times[-1]
display = simple.Show(reader, view)
simple.ColorBy(display, ("CELLS", FIELD))
lut = simple.GetColorTransferFunction(FIELD)
display.RescaleTransferFunctionToDataRange(True, False)
warp = simple.WarpByVector(Input=reader)
warp.Vectors = ["POINTS", "displacement"]
warp.ScaleFactor = 100.0
warp.UpdatePipeline(times[-1])
warped = servermanager.Fetch(warp)
print(json.dumps({"reader": reader.GetXMLName(), "times": times, "steps": steps,
                  "sigma_zz_colour_range": list(lut.RGBPoints[0::4][:1] + lut.RGBPoints[0::4][-1:]),
                  "warped_points": warped.GetNumberOfPoints()}))
