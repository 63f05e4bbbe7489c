#pragma once
/// The tables a bench prints as Markdown, kept cell by cell so that `--json FILE` writes the
/// same tables for scripts (python/chromasim/figures.py) to read.
///
/// The JSON file: {"command": "bench render" | "bench mechanics", "chromasim_version": "X.Y.Z",
/// "tables": [{"caption": "...", "header": ["integrator", ...], "rows": [["fast", ...], ...]}]}.
/// Every cell is a string, the text the Markdown cell shows ("101.3", "-0.372 %",
/// "37565 (once per sensor)", "" for an empty cell); a reader takes the numbers from them.
#include <filesystem>
#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

namespace chromasim::generators {

struct BenchTable {
    std::string caption; ///< the line printed before the table
    std::vector<std::string> header;
    std::vector<std::vector<std::string>> rows;
};

/// A table printed as it grows: the caption, a blank line, the header and the |---| row at
/// once, then each row as it is added ("| a | b |"; an empty cell "| |").
class TablePrinter {
public:
    TablePrinter(BenchTable head, std::ostream& out);
    void row(std::vector<std::string> cells);
    const BenchTable& table() const { return m_table; }

private:
    BenchTable m_table;
    std::ostream& m_out;
};

/// Before any work: throws std::invalid_argument naming `command`, --json and `path` unless
/// `path` is a file name in a folder that exists and can be written (empty: no file asked).
void check_json_out(std::string_view command, const std::filesystem::path& path);

/// The JSON text of the tables (the shape above).
std::string bench_json(std::string_view command, const std::vector<BenchTable>& tables);

/// Writes bench_json to `path` whole (a temporary file renamed); empty `path`: nothing.
void write_bench_json(const std::filesystem::path& path, std::string_view command,
                      const std::vector<BenchTable>& tables);

} // namespace chromasim::generators
