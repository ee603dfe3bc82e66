// Depth only: the rasteriser writes the depth the comparison reads.
void main() {}
