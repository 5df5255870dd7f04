"""Run by pvbatch: the plastic zone of a wedge_rock run (demos/wedge_indentation.py) in
ParaView, its default reader on fields.xdmf, coloured by eps_p_eq at the last time.

    xvfb-run -a pvbatch demos/wedge_rock_picture.py RUN/fields.xdmf docs/figures/wedge_rock.png
"""
import sys

from paraview import simple

reader = simple.OpenDataFile(sys.argv[1])  # the reader ParaView picks for the file
reader.UpdatePipelineInformation()
last = float(reader.TimestepValues[-1])
view = simple.CreateRenderView()
view.ViewSize = [1200, 800]
view.ViewTime = last
view.OrientationAxesVisibility = 0
view.Background = [1.0, 1.0, 1.0]
try:
    view.UseColorPaletteForBackground = 0
except AttributeError:
    pass
display = simple.Show(reader, view)
simple.ColorBy(display, ("CELLS", "eps_p_eq"))
lut = simple.GetColorTransferFunction("eps_p_eq")
lut.RescaleTransferFunction(0.0, 0.01)  # the crushed zone; larger strains saturate
display.SetScalarBarVisibility(view, True)
bar = simple.GetScalarBar(lut, view)
bar.Title = "eps_p_eq (-)"
bar.ComponentTitle = ""
bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
simple.Render(view)  # the first render places the camera on the whole mesh: set it after
# the tip and the rock under it: 28 mm wide, from 2.5 mm above the rock's top to 16.5 mm below
view.CameraPosition = [0.011, -0.007, 0.05]
view.CameraFocalPoint = [0.011, -0.007, 0.0]
view.CameraViewUp = [0.0, 1.0, 0.0]
view.CameraParallelProjection = 1
view.CameraParallelScale = 0.0095
simple.Render(view)
simple.SaveScreenshot(sys.argv[2], view, ImageResolution=[1200, 800])
