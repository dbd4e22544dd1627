# Writes the textures of scenes/cornell-textured.json as 8-bit sRGB PNGs (Python's zlib alone, no
# imaging library):
#
#   python3 scenes/textures/make_textures.py scenes/textures
#
# checker.png: 256 x 256 texels, 8 x 8 tiles of 32, light (sRGB 220, linear 0.716) and dark (sRGB 60,
# linear 0.0452); mean reflectance 0.3805 (the tests compute it from the bytes).
# stripes.png: 256 x 16 texels, vertical stripes of 32 texels, warm (sRGB 230, 190, 150) and cool
# (sRGB 120, 150, 200) in turn.
import struct
import sys
import zlib


def write_png(path, width, height, pixel):
    rows = b"".join(b"\0" + b"".join(bytes(pixel(x, y)) for x in range(width)) for y in range(height))
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(rows, 9)) + chunk(b"IEND", b"")
    open(path, "wb").write(png)


folder = sys.argv[1]
write_png(f"{folder}/checker.png", 256, 256,
          lambda x, y: (220, 220, 220) if (x // 32 + y // 32) % 2 == 0 else (60, 60, 60))
write_png(f"{folder}/stripes.png", 256, 16,
          lambda x, y: (230, 190, 150) if (x // 32) % 2 == 0 else (120, 150, 200))
