"""Model files shipped inside the package (package data): yolox_nano.onnx, the appearance
detector's default model, with its licence (LICENSE.yolox_nano.txt) and NOTICE.md."""
