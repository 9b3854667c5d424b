// SPDX-License-Identifier: BSD-3-Clause
#include "fnmpc/config/csv_reader.hpp"

#include <gtest/gtest.h>

#include <string>

namespace fnmpc::config {
namespace {

// The message of the ConfigError thrown by parsing `text` ("" when none).
std::string ErrorOf(const std::string& text, const std::vector<std::string>& cols,
                    const std::string& time = "t") {
  try {
    ParseCsv(text, "log.csv", cols, time);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(CsvReaderTest, ReadsColumnsInAnyOrderAndIgnoresExtras) {
  // Given columns in another order with an extra one,
  const std::string text = "angle,extra,t\n0.5,x,0.0\n0.25,y,0.1\n";
  // When the required columns are read,
  const CsvTable tab = ParseCsv(text, "p.csv", {"t", "angle"}, "t");
  // Then they hold the values by name.
  ASSERT_EQ(tab.rows(), 2u);
  EXPECT_DOUBLE_EQ(tab.Column("t")[1], 0.1);
  EXPECT_DOUBLE_EQ(tab.Column("angle")[0], 0.5);
  EXPECT_THROW((void)tab.Column("extra"), std::invalid_argument);
}

TEST(CsvReaderTest, MissingColumnNamesFileLineAndColumn) {
  // Given a header without 'angle', When read, Then the error names file, header line, column.
  const std::string msg = ErrorOf("\nt,x\n0,1\n", {"t", "angle"});
  EXPECT_NE(msg.find("log.csv:2:1: column 'angle': missing required column"), std::string::npos)
      << msg;
}

TEST(CsvReaderTest, NonNumericCellNamesLineAndCharacterColumn) {
  // Given a bad cell in row 3, second field starting at character 5,
  const std::string msg = ErrorOf("t,angle\n0,1\n0.1,abc\n", {"t", "angle"});
  // When read, Then the error points at it.
  EXPECT_NE(msg.find("log.csv:3:5: column 'angle': not a number: 'abc'"), std::string::npos) << msg;
}

TEST(CsvReaderTest, NanAndEmptyAndShortRowsAreErrors) {
  // Given a NaN, an empty cell and a short row, When read, Then each is an error with position.
  EXPECT_NE(ErrorOf("t,angle\n0,nan\n", {"t", "angle"})
                .find("log.csv:2:3: column 'angle': not "
                      "a finite number"),
            std::string::npos);
  EXPECT_NE(ErrorOf("t,angle\n0,\n", {"t", "angle"})
                .find("log.csv:2:3: column 'angle': not a "
                      "number: ''"),
            std::string::npos);
  EXPECT_NE(ErrorOf("t,angle\n0,1\n0.2\n", {"t", "angle"}).find("log.csv:3:"), std::string::npos);
  EXPECT_NE(ErrorOf("t,angle\n", {"t", "angle"}).find("no data rows"), std::string::npos);
}

TEST(CsvReaderTest, NonIncreasingTimeIsAnError) {
  // Given time that repeats at line 4, When read, Then the error names line 4, column 1.
  const std::string msg = ErrorOf("t,angle\n0,1\n0.1,1\n0.1,2\n", {"t", "angle"});
  EXPECT_NE(msg.find("log.csv:4:1: column 't': time does not increase"), std::string::npos) << msg;
}

TEST(CsvReaderTest, MissingFileIsAnError) {
  EXPECT_THROW(ReadCsv("/nonexistent/file.csv", {"t"}), ConfigError);
}

}  // namespace
}  // namespace fnmpc::config
