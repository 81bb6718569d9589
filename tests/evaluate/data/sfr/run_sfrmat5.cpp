// Driver (written for edgetruth's reference data): read a single-channel float64 image
// (raw file: int32 rows, int32 cols, rows*cols doubles, row-major), run the t-kuha C++
// port of sfrmat5 with npol = argv[2] (default 5), Tukey window, del = 1, and print JSON.
#include "sfrmat5.h"
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>

int main(int argc, char** argv) {
    if (argc < 2) { std::cerr << "usage: run_sfrmat5 image.raw [npol] [hamming]\n"; return 2; }
    std::ifstream in(argv[1], std::ios::binary);
    int32_t rows = 0, cols = 0;
    in.read(reinterpret_cast<char*>(&rows), 4);
    in.read(reinterpret_cast<char*>(&cols), 4);
    sfrmat5::Image<double> img(rows, cols, 1, 0.0);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            double v; in.read(reinterpret_cast<char*>(&v), 8); img.planes[0](r, c) = v;
        }
    if (!in) { std::cerr << "short read\n"; return 1; }
    sfrmat5::SfrMat5<double> sfr;
    sfr.set_npol(argc > 2 ? std::atoi(argv[2]) : 5);
    if (argc > 3 && std::string(argv[3]) == "hamming") sfr.set_wflag(sfrmat5::WindowFlag::Hamming);
    sfrmat5::SfrResult<double> res = sfr.compute(img);
    std::printf("{\"status\": %d, \"sfr50\": %.8f, \"del2\": %.10f, \"nbin\": %d, \"fitme\": [", res.status, res.sfr50, res.del2, res.nbin);
    for (int c = 0; c < res.fitme.cols(); ++c) std::printf("%s%.12g", c ? ", " : "", res.fitme(0, c));
    std::printf("], \"freq\": [");
    for (int i = 0; i < res.dat.rows(); ++i) std::printf("%s%.10g", i ? ", " : "", res.dat(i, 0));
    std::printf("], \"sfr\": [");
    for (int i = 0; i < res.dat.rows(); ++i) std::printf("%s%.10g", i ? ", " : "", res.dat(i, 1));
    std::printf("]}\n");
    return 0;
}
