"""Image intake: every image file a C-arm or a frame grabber hands over, read by the
standard into :class:`Frame` objects on the detector's own pixel grid, and the writers.

- :func:`read_frames` / :func:`read_frame` / :func:`frame_count` — a file (PNG, TIFF, JPEG,
  BMP, GIF, WebP, NumPy ``.npy``, DICOM; found by content, the suffix as a fallback) or a directory of them
  (a run, natural order of names); multi-frame DICOM, multi-page TIFF and ``(n, H, W)``
  arrays are runs; frames are decoded one at a time.
- :func:`read_image` — the first frame as the old ``(pixels, camera, meta)`` tuple.
- :func:`write_image` — one image (PNG/TIFF/NPY/DICOM, atomic); :func:`write_dicom` — the
  test-data DICOM writer (XA, RF, DX, CR, Enhanced XA/XRF, every case below).
- :class:`DistortionModel`, :func:`read_distortion` / :func:`write_distortion`,
  :func:`undistort_image` / :func:`distort_image` — an image intensifier's distortion as a
  2-D polynomial from ideal (pinhole) to imaged pixels (:mod:`.distortion`).

Bad input of any kind is an :class:`~ftrac_design.errors.InputError` (file, key, expected);
a header that lies is refused before anything is allocated (at most 4096 × 4096 pixels a
frame).

DICOM attributes honoured, as attribute (tag) [where it is read; in enhanced objects a named
functional group is looked in per frame, then shared, then the top level]: what intake does.

- Rows, Columns, Number of Frames (0028,0010/0011/0008) [top]: frame size and count; must match
  the native pixel data's length; refused above 4096² pixels.
- Samples per Pixel, Photometric Interpretation (0028,0002/0004) [top]: MONOCHROME1/2 grey;
  RGB/YBR (a grabber's DICOM) → Rec. 709 grey with a note; others refused. MONOCHROME1 values
  are kept as stored (it is a display statement).
- Bits Allocated, Bits Stored, High Bit, Pixel Representation (0028,0100/0101/0102/0103) [top]:
  bits above Bits Stored masked off; two's-complement sign restored; Bits Stored > Bits
  Allocated or High Bit ≠ Bits Stored − 1 refused.
- Transfer Syntax UID (0002,0010) [file meta information]: native, RLE Lossless, JPEG Lossless
  (SV1 and others), JPEG-LS, JPEG 2000 via pydicom + pylibjpeg plug-ins; a missing codec →
  InputError naming the UID, its name and the package.
- Modality LUT Sequence (0028,3000) [top]: applied (pydicom); a decreasing LUT reverses the
  polarity.
- Rescale Slope / Intercept (0028,1053/1052) [Pixel Value Transformation (0028,9145), top]:
  applied; a negative slope reverses the polarity.
- VOI LUT, Window Center/Width (0028,3010), (0028,1050/1051): never applied (display only).
- Pixel Intensity Relationship (0028,1040) [Frame Pixel Data Properties (0028,9443), top]:
  LIN/LOG/DISP → `formation` linear/log/display.
- Pixel Intensity Relationship Sign (0028,1041) [Frame Pixel Data Properties, top]: +1 →
  `polarity` dense-dark, −1 → dense-bright (PS3.3 C.8.11.3.1.2); without it LIN → dense-dark,
  else none.
- Field of View Rotation / Horizontal Flip (0018,7032/7034) [Field of View (0018,9432), top]:
  undone (flip, then the clockwise rotation), so pixels are on the detector grid; spacing axes
  swapped for 90°/270°.
- Field of View Origin (0018,7030) [Field of View, top]: places the stored grid on the detector
  for the principal point.
- Imager Pixel Spacing (0018,1164) [Frame Pixel Data Properties, top]: pixel pitch (row, column
  spacing) at the detector: the camera's s_y, s_x.
- Pixel Spacing, Pixel Spacing Calibration Type (0028,0030), (0028,0A02) [Pixel Measures
  (0028,9110), top]: pitch when Imager Pixel Spacing is absent: as is without a calibration
  type; calibrated (GEOMETRY/FIDUCIAL) → × Estimated Radiographic Magnification Factor, else
  refused as a pitch.
- Estimated Radiographic Magnification Factor (0018,1114) [top]: brings a calibrated Pixel
  Spacing back to the detector plane.
- Distance Source to Detector (0018,1110) [X-Ray Geometry (0018,9476), top]: focal length f
  (mm).
- Position of Isocenter Projection (0018,9430) [top (X-Ray Detector module)]: principal point
  (fractional detector elements, via Field of View Origin and Detector Element Spacing
  (0018,7022)).
- Physical Detector Size (0018,9429) [top]: principal point at the detector centre when no
  isocentre projection is given.
- Frame Time, Frame Time Vector (0018,1063/1065) [top]: `time_s` of each frame.
- Frame Acquisition / Reference DateTime (0018,9074/9151) [Frame Content (0020,9111)]: `time_s`
  from the first frame (enhanced objects).
- Positioner Primary / Secondary Angle (0018,1510/1511) [Positioner Position (0018,9405), top]:
  kept in `meta` (degrees).
- Image Comments (0020,4000) [top]: our own note (camera, polarity) as a fallback.

Missing Distance Source to Detector or pixel spacing (and no ``camera``) → InputError naming
the tags and the ways out (``--camera C.json``, or intrinsics estimated from the fiducial
over several frames); ``need_camera=False`` gives ``camera=None`` instead. The principal
point without a tag is the image centre ((W − 1)/2, (H − 1)/2); ``Frame.camera_source`` says
which source each intrinsic came from.

Rasters: 8/16-bit PNG, TIFF (8/16/32-bit integers, floats; palette, bilevel, MinIsWhite, CMYK;
each page a frame; pages of different shapes refused naming the page), JPEG (a note: lossy),
BMP, GIF and WebP (screen captures and grabbers; an animated one is a run); colour → Rec. 709 grey and
alpha dropped, with notes; our note's camera, polarity, formation and linear map are used.
NumPy: ``allow_pickle=False``; (n, H, W) is a run; an ``.npz`` named ``.npy`` is refused.
"""

from .distortion import DistortionModel, distort_image, read_distortion, undistort_image, write_distortion
from .frame import MAX_FRAME_PIXELS, Formation, Frame, Polarity
from .runs import frame_count, read_frame, read_frames, read_image
from .write import write_image
from .write_dicom import write_dicom

__all__ = [
    "Frame",
    "Formation",
    "Polarity",
    "MAX_FRAME_PIXELS",
    "frame_count",
    "read_frame",
    "read_frames",
    "read_image",
    "write_image",
    "write_dicom",
    "DistortionModel",
    "read_distortion",
    "write_distortion",
    "undistort_image",
    "distort_image",
]
