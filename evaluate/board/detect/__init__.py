"""Finding the board in a photo: dark quads (``quads``), which is which square (``correspond``), a chessboard's
grid (``chessboard``), the squares' flat levels (``levels``) and the model's squares in the photo (``squares``)."""
