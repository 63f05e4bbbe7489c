#include "generators/output/csv_rows.hpp"

#include "generators/spec/spec.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>

namespace chromasim::generators {

std::vector<std::string> split_csv(const std::string& line) {
    std::vector<std::string> out;
    std::stringstream in(line);
    std::string cell;
    while (std::getline(in, cell, ','))
        out.push_back(cell);
    if (!line.empty() && line.back() == ',') out.emplace_back();
    return out;
}

CsvRows::CsvRows(const std::filesystem::path& dir, const std::string& name,
                 const std::string& error_prefix)
    : m_name(name), m_path(dir / name), m_in(dir / name) {
    std::string header;
    if (!m_in || !std::getline(m_in, header))
        throw SpecError(error_prefix + m_path.string() + ": missing or empty");
    const std::vector<std::string> names = split_csv(header);
    for (std::size_t i = 0; i < names.size(); ++i)
        m_columns[names[i]] = i;
}

bool CsvRows::next() {
    if (!std::getline(m_in, m_line)) return false;
    ++m_number;
    m_cells = split_csv(m_line);
    return true;
}

const std::string& CsvRows::cell(const std::string& column) const {
    static const std::string empty;
    const auto it = m_columns.find(column);
    return it != m_columns.end() && it->second < m_cells.size() ? m_cells[it->second] : empty;
}

double CsvRows::number(const std::string& column) const {
    const std::string& text = cell(column);
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || *end != '\0' || !std::isfinite(v))
        throw SpecError(m_path.string() + ":" + std::to_string(line()) + ": column " + column +
                        ": '" + text + "' is not a finite number");
    return v;
}

} // namespace chromasim::generators
