#pragma once
// File helpers of the generator tests: a fresh temporary folder per process, labels.csv rows
// by column name, a file's bytes, a spec text's error.
#include "generators/spec/spec.hpp"

#include <catch2/catch.hpp>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace chromasim::generators::test {

/// The SpecError message that parsing `yaml` (as "bad.yaml") raises; fails the test if none.
inline std::string error_of(const std::string& yaml) {
    try {
        parse_spec(yaml, "bad.yaml");
    } catch (const SpecError& e) {
        return e.what();
    }
    FAIL("no SpecError for:\n" << yaml);
    return "";
}

/// An empty path under the temporary folder; one per process (CTest may run test cases in
/// parallel processes).
inline std::filesystem::path fresh_dir(const std::string& name) {
    const std::filesystem::path p = std::filesystem::temp_directory_path() /
                                    ("chromasim_test_" + name + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(p);
    return p;
}

/// A CSV file's rows, each a map from the header's column names to the values.
using CsvRow = std::map<std::string, std::string>;
inline std::vector<CsvRow> read_csv(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::string line;
    std::getline(in, line);
    std::vector<std::string> header;
    std::stringstream hs(line);
    for (std::string h; std::getline(hs, h, ',');)
        header.push_back(h);
    std::vector<CsvRow> rows;
    while (std::getline(in, line)) {
        std::stringstream ls(line);
        CsvRow row;
        std::string v;
        for (const auto& h : header) {
            std::getline(ls, v, ',');
            row[h] = v;
        }
        rows.push_back(row);
    }
    return rows;
}

/// The numeric value of a column, required finite.
inline double num(const CsvRow& r, const std::string& key) {
    const double v = std::stod(r.at(key));
    REQUIRE(std::isfinite(v));
    return v;
}

inline std::string file_bytes(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

} // namespace chromasim::generators::test
