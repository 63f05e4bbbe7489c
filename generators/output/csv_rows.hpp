#pragma once
/// A dataset's CSV files (labels.csv, markers.csv) read back row by row, cells by column name.
/// Plain comma-separated cells, as dataset_writer writes them (no quoting).
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace chromasim::generators {

/// Splits one CSV line at its commas; a trailing comma gives an empty last cell.
std::vector<std::string> split_csv(const std::string& line);

class CsvRows {
public:
    /// Opens dir/name and reads its header. Throws SpecError "<error_prefix><path>: missing or
    /// empty" when it cannot.
    CsvRows(const std::filesystem::path& dir, const std::string& name,
            const std::string& error_prefix = "");
    /// Reads the next row; false at the end of the file.
    bool next();
    bool has(const std::string& column) const { return m_columns.count(column) > 0; }
    /// The cell of `column` in the current row ("" when the column or the cell is absent).
    const std::string& cell(const std::string& column) const;
    /// The cell of `column` as a number; throws SpecError naming the file, line and column when
    /// it is not one.
    double number(const std::string& column) const;
    long line() const { return m_number + 1; } ///< the current row's line in the file
    const std::string& name() const { return m_name; }

private:
    std::string m_name;
    std::filesystem::path m_path;
    std::ifstream m_in;
    std::map<std::string, std::size_t> m_columns;
    std::string m_line;
    std::vector<std::string> m_cells;
    long m_number = 0;
};

} // namespace chromasim::generators
