#include "generators/validation/bench_table.hpp"

#include "generators/io/file_io.hpp"

#include <nlohmann/json.hpp>
#include <unistd.h>

#include <ostream>
#include <stdexcept>
#include <utility>

namespace chromasim::generators {

namespace {

void print_row(const std::vector<std::string>& cells, std::ostream& out) {
    out << "|";
    for (const std::string& cell : cells)
        out << " " << cell << (cell.empty() ? "" : " ") << "|";
    out << "\n";
}

} // namespace

TablePrinter::TablePrinter(BenchTable head, std::ostream& out)
    : m_table(std::move(head)), m_out(out) {
    m_out << m_table.caption << "\n\n";
    print_row(m_table.header, m_out);
    m_out << "|";
    for (std::size_t i = 0; i < m_table.header.size(); ++i)
        m_out << "---|";
    m_out << "\n";
}

void TablePrinter::row(std::vector<std::string> cells) {
    print_row(cells, m_out);
    m_table.rows.push_back(std::move(cells));
}

void check_json_out(std::string_view command, const std::filesystem::path& path) {
    if (path.empty()) return;
    namespace fs = std::filesystem;
    const fs::path folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
    std::string why;
    std::error_code ec;
    if (fs::is_directory(path, ec))
        why = "it is a folder";
    else if (!fs::exists(folder, ec))
        why = "the folder " + folder.string() + " does not exist";
    else if (!fs::is_directory(folder, ec))
        why = folder.string() + " is not a folder";
    else if (::access(folder.c_str(), W_OK) != 0)
        why = "the folder " + folder.string() + " cannot be written";
    if (why.empty()) return;
    throw std::invalid_argument(std::string(command) + ": --json " + path.string() + ": " + why +
                                "; allowed: a file in a folder that exists and can be written");
}

std::string bench_json(std::string_view command, const std::vector<BenchTable>& tables) {
    using Json = nlohmann::ordered_json; // keys in the order written
    Json list = Json::array();
    for (const BenchTable& t : tables)
        list.push_back(Json{{"caption", t.caption}, {"header", t.header}, {"rows", t.rows}});
    const Json j{{"command", std::string(command)},
                 {"chromasim_version", CHROMASIM_VERSION},
                 {"tables", std::move(list)}};
    return j.dump(1, ' ', false, Json::error_handler_t::replace) + "\n";
}

void write_bench_json(const std::filesystem::path& path, std::string_view command,
                      const std::vector<BenchTable>& tables) {
    if (path.empty()) return;
    write_file_atomic(path, bench_json(command, tables));
}

} // namespace chromasim::generators
